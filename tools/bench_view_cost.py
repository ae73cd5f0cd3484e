"""Issue 17's cost of a browser: `afe serve` computing the default cues {ratemap, ild,
itd, ic} of a synthetic 44.1-kHz source at real time in 10-ms blocks, with and without
one headless Chromium page of the live view attached, in alternating rounds. Prints one
JSON line per run (the server's compute per block: p50, p99, max in ms, deadline misses,
frames lost, and for the page the batches it drew and the frames it lost) and a summary
with the median p99 of each side and their ratio.

    python tools/bench_view_cost.py [--afe target/release/afe] [--rounds 3] [--seconds 20]

Needs Debian's chromium and chromium-driver, and selenium.
"""

import argparse
import json
import shutil
import socket
import statistics
import subprocess
import time

SOURCE = "synth:fs=44100,tone=440,noise=0.1,itd_ms=0.4,ild_db=-6,seed=1"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_port(port, proc):
    end = time.monotonic() + 10
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise SystemExit(f"afe serve exited: {proc.stderr.read()}")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    raise SystemExit("afe serve did not listen")


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,1400"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=opts)


def run(afe, seconds, with_page, threads):
    port = free_port()
    server = subprocess.Popen(
        [afe, "serve", "--source", SOURCE, "-r", "ratemap,ild,itd,ic", "--threads", str(threads),
         "--http", f"127.0.0.1:{port}", "--listen", "tcp/127.0.0.1:0", "--for", str(seconds), "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    wait_for_port(port, server)
    page = {}
    if with_page:
        from selenium.webdriver.common.by import By
        from selenium.webdriver.support.ui import WebDriverWait

        b = browser()
        try:
            b.get(f"http://127.0.0.1:{port}/")
            WebDriverWait(b, 10).until(lambda d: d.find_element(By.ID, "conn").text == "live")
            while server.poll() is None:
                page = {
                    "page_frames": int(b.find_element(By.ID, "frames").text or 0),
                    "page_lost": int(b.find_element(By.ID, "lost").text or 0),
                }
                time.sleep(0.5)
        finally:
            b.quit()
    out, err = server.communicate(timeout=seconds + 30)
    if server.returncode != 0:
        raise SystemExit(f"afe serve failed: {err}")
    report = json.loads(out.strip().splitlines()[-1])
    result = {
        "page": with_page,
        "p50_ms": report["compute_ms_p50"],
        "p99_ms": report["compute_ms_p99"],
        "max_ms": report["compute_ms_max"],
        "misses": report["deadline_misses"],
        "lost_frames": report["lost_frames"],
        **page,
    }
    print(json.dumps(result), flush=True)
    return result


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--afe", default="target/release/afe")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--threads", type=int, default=0)
    args = ap.parse_args()
    runs = [run(args.afe, args.seconds, with_page, args.threads)
            for _ in range(args.rounds) for with_page in (False, True)]
    p99 = {side: statistics.median(r["p99_ms"] for r in runs if r["page"] == side) for side in (False, True)}
    print(json.dumps({"median_p99_ms_without_page": p99[False], "median_p99_ms_with_page": p99[True],
                      "ratio": p99[True] / p99[False]}))


if __name__ == "__main__":
    main()
