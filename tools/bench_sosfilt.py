"""Issue 14's filterbank yardstick: `afe bench IN -r filterbank -p fb_nChannels=32
--threads 0` against scipy's `sosfilt` doing the same number of second-order sections
(four per channel and ear, the order-4 gammatone), in the same run, alternating.

    python tools/bench_sosfilt.py IN.wav [--afe target/release/afe] [--rounds 5]

Prints one JSON line: each side's best and median wall time and the ratio of the bests.
"""

import argparse
import json
import statistics
import subprocess
import time
import wave

import numpy as np
from scipy import signal


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("wav")
    ap.add_argument("--afe", default="target/release/afe")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--channels", type=int, default=32)
    args = ap.parse_args()
    with wave.open(args.wav) as w:
        fs, ears, n = w.getframerate(), w.getnchannels(), w.getnframes()
        x = np.frombuffer(w.readframes(n), dtype="<i2").reshape(n, ears).T / 32768.0
    # 4 sections per channel (a band-pass per centre frequency), every channel of both ears
    cfs = np.geomspace(80, 8000, args.channels)
    sos = [signal.butter(2, [cf / 1.2, cf * 1.2], "bandpass", fs=fs, output="sos") for cf in cfs]
    afe_times, scipy_times = [], []
    for _ in range(args.rounds):
        out = subprocess.run(
            [args.afe, "bench", args.wav, "-r", "filterbank", "-p", f"fb_nChannels={args.channels}",
             "--threads", "0", "--repeat", "1", "--json"],
            check=True, capture_output=True, text=True,
        )
        afe_times.append(json.loads(out.stdout.strip().splitlines()[-1])["wall_seconds_min"])
        t = time.perf_counter()
        for ear in x:
            for s in sos:
                signal.sosfilt(np.vstack([s, s]), ear)
        scipy_times.append(time.perf_counter() - t)
    print(json.dumps({
        "input": args.wav, "seconds": n / fs, "channels": args.channels, "ears": ears,
        "afe_best_s": min(afe_times), "afe_median_s": statistics.median(afe_times),
        "sosfilt_best_s": min(scipy_times), "sosfilt_median_s": statistics.median(scipy_times),
        "ratio_of_bests": min(scipy_times) / min(afe_times),
    }))


if __name__ == "__main__":
    main()
