"""The live cost of `afe serve --ros2`: the server's compute per 10-ms block (p50, p99)
and its frames lost with four ROS 2 subscribers (plain Zenoh sessions on the node's data
keys, as rmw_zenoh subscribers are) and one afe.connect client, beside the same run
without --ros2 (the client alone); then a stalled ROS subscriber beside a keeping one,
counting what each lost by its samples' sequence numbers.

    python tools/bench_ros2_cost.py [--cli target/release/afe] [--seconds 20]
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import threading
import time


HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python", "tests"))
from conftest import free_port, zenoh_peer as session  # noqa: E402
from test_ros2 import dds, typestore  # noqa: E402  (the message definitions, via rosbags)

REQUESTS = ["ratemap", "ild", "itd", "ic"]
SOURCE = "synth:fs=44100,tone=500,noise=0.1,itd_ms=0.3,seed=5"


def key(store, topic, ty):
    return f"0/afe/{topic}/{dds(ty)}/{store.hash_rihs01(ty)}"


def add(s, store, request):
    ty = "afe_msgs/srv/AddRequest"
    msg = store.types[f"{ty}_Request"](request=request, parameters=[])
    att = struct.pack("<qqB", 1, time.time_ns(), 16) + os.urandom(16)
    for _ in range(100):
        replies = [r for r in s.get(key(store, "add_request", ty),
                                    payload=bytes(store.serialize_cdr(msg, f"{ty}_Request")),
                                    attachment=att, timeout=5.0) if r.ok]
        if replies:
            return store.deserialize_cdr(replies[0].ok.payload.to_bytes(), f"{ty}_Response")
        time.sleep(0.1)
    raise RuntimeError("the node does not answer add_request")


class Counter:
    """A subscriber counting samples and the gaps in their sequence numbers."""

    def __init__(self, s, k, stall_s=0.0):
        self.n, self.lost, self.last, self.stall_s = 0, 0, None, stall_s
        self.sub = s.declare_subscriber(k, self.on)

    def on(self, sample):
        seq = struct.unpack("<q", sample.attachment.to_bytes()[:8])[0]
        if self.last is not None and seq > self.last + 1:
            self.lost += seq - self.last - 1
        self.last, self.n = seq, self.n + 1
        if self.stall_s:
            time.sleep(self.stall_s)


def run(cli, seconds, ros2, stalled=False):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cmd = [cli, "serve", "--source", SOURCE, "--listen", endpoint, "--block-ms", "10",
           "--for", str(seconds), "--json", "-r", ",".join(REQUESTS)]
    if ros2:
        cmd.append("--ros2")
    server = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    store = typestore()
    import afe
    client = None
    for _ in range(100):
        try:
            client = afe.connect(endpoint, timeout=5.0)
            break
        except Exception:
            time.sleep(0.1)
    sub = client.subscribe(REQUESTS)
    got = [0]
    threading.Thread(target=lambda: [got.__setitem__(0, got[0] + 1) for _ in sub],
                     daemon=True).start()
    counters, sessions = [], []
    if ros2:
        s0 = session(endpoint)
        sessions.append(s0)
        topics = []
        for r in ("ratemap", "ild"):
            topics += [t.split("/")[-1] for t in add(s0, store, r).topics]
        wanted = [(t, "afe_msgs/msg/Signal") for t in topics] + [("audio", "afe_msgs/msg/Audio")]
        for i, (t, ty) in enumerate(wanted[:4]):
            s = session(endpoint)
            sessions.append(s)
            counters.append((t, Counter(s, key(store, t, ty))))
        if stalled:
            s = session(endpoint)
            sessions.append(s)
            counters.append(("stalled " + wanted[0][0],
                             Counter(s, key(store, wanted[0][0], wanted[0][1]), stall_s=0.5)))
    report = json.loads(server.communicate()[0])
    for s in sessions:
        s.close()
    client.close()
    return report, counters, got[0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", default=os.path.join(HERE, "..", "target", "release", "afe"))
    ap.add_argument("--seconds", type=float, default=20.0)
    a = ap.parse_args()
    for label, ros2, stalled in [("without --ros2", False, False),
                                 ("--ros2, 4 ROS subscribers", True, False),
                                 ("without --ros2", False, False),
                                 ("--ros2, 4 ROS subscribers", True, False),
                                 ("--ros2, 4 + a stalled one", True, True)]:
        rep, counters, frames = run(a.cli, a.seconds, ros2, stalled)
        print(f"{label:28s} p50 {rep['compute_ms_p50']:.3f} ms  p99 {rep['compute_ms_p99']:.3f} ms"
              f"  max {rep['compute_ms_max']:.3f} ms  frames lost {rep['lost_frames']}"
              f"  misses {rep['deadline_misses']}  client messages {frames}  ({rep['host']})")
        for t, c in counters:
            print(f"    {t:24s} {c.n:5d} samples, {c.lost} lost")


if __name__ == "__main__":
    main()
