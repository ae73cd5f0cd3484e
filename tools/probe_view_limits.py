"""Issue 44's hostile pages against the live view: `afe serve -r ratemap` of a synthetic
44.1-kHz source at real time, then a WebSocket from a foreign origin, then PAGES pages of
the server's own origin at once, FLOODERS of them each sending 1,000 `ild` adds (every
one with other parameters) and asking for the audio. Prints the foreign origin's answer,
the server's memory before and after (VmRSS, VmHWM), what the pages were told (adds
placed and refused, pages refused), and the stream's report (frames lost, deadline
misses, compute per block).

    python tools/probe_view_limits.py [--afe target/release/afe] [--pages 200] [--flooders 5]

Needs websocket-client (pip install websocket-client) and an `afe` built with
`--features robot`.
"""

import argparse
import json
import socket
import subprocess
import threading
import time

import websocket

SOURCE = "synth:fs=44100,tone=440,noise=0.1,seed=1"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def memory(pid):
    with open(f"/proc/{pid}/status") as f:
        return {l.split(":")[0]: l.split(":")[1].strip() for l in f if l.startswith(("VmRSS", "VmHWM"))}


def page(url, origin, adds, seed, told, lock):
    try:
        ws = websocket.create_connection(url, origin=origin, timeout=10)
    except (OSError, websocket.WebSocketException):
        with lock:
            told["connect failed"] += 1
        return
    for k in range(adds):
        params = {"fb_nChannels": 4 + (seed * adds + k) % 60}
        ws.send(json.dumps({"op": "add", "request": "ild", "params": params}))
    ws.send(json.dumps({"op": "audio", "on": True}))
    end = time.monotonic() + 8
    try:
        while time.monotonic() < end:
            op, data = ws.recv_data()
            if op == websocket.ABNF.OPCODE_CLOSE:
                return
            if op != websocket.ABNF.OPCODE_TEXT:
                continue
            msg = json.loads(data)
            key = None
            if msg.get("type") == "refused":
                key = "pages refused"
            elif msg.get("type") == "reply" and msg.get("op") == "add":
                key = "adds placed" if msg["ok"] else "adds refused"
            elif msg.get("type") == "reply" and not msg["ok"]:
                key = "messages refused"
            if key:
                with lock:
                    told[key] += 1
    except (OSError, websocket.WebSocketException):
        pass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--afe", default="target/release/afe")
    ap.add_argument("--pages", type=int, default=200)
    ap.add_argument("--flooders", type=int, default=5)
    args = ap.parse_args()
    port = free_port()
    server = subprocess.Popen(
        [args.afe, "serve", "--source", SOURCE, "-r", "ratemap", "--http", f"127.0.0.1:{port}",
         "--listen", "tcp/127.0.0.1:0", "--for", "20", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    time.sleep(1.0)
    url = f"ws://127.0.0.1:{port}/ws"
    try:
        websocket.create_connection(url, origin="http://evil.example", timeout=5)
        print("foreign origin: accepted")
    except websocket.WebSocketBadStatusException as e:
        print(f"foreign origin: HTTP {e.status_code}")
    print("memory before:", memory(server.pid))
    told = {k: 0 for k in ("adds placed", "adds refused", "messages refused", "pages refused",
                           "connect failed")}
    lock = threading.Lock()
    own = f"http://127.0.0.1:{port}"
    pages = [threading.Thread(target=page, args=(url, own, 1000 if i < args.flooders else 0, i,
                                                 told, lock))
             for i in range(args.pages)]
    for i, p in enumerate(pages):
        p.start()
        if i + 1 == args.flooders:
            time.sleep(0.5)  # the flooders connect first
    for p in pages:
        p.join()
    print(f"{args.pages} pages, {args.flooders} flooding:", told)
    print("memory after:", memory(server.pid))
    out, _ = server.communicate(timeout=30)
    report = json.loads(out)
    print({k: report.get(k) for k in ("blocks", "lost_frames", "deadline_misses",
                                      "compute_ms_p50", "compute_ms_p99")})


if __name__ == "__main__":
    main()
