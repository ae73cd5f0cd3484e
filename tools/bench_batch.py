"""Benchmark of `afe batch` (issue 15): N files of S seconds (binaural, 44.1 kHz) with
{ratemap, ild, itd, ic}, timed as `afe extract` of each file one after another,
`afe batch -j 1`, `afe batch -j 2`, and afe.batch on a Dask LocalCluster of 2 workers;
then the peak RSS of `afe batch -j 2` over a 1-hour file and a few short ones.

    python tools/bench_batch.py --afe target/release/afe [--files 200] [--seconds 10]

Needs numpy, and dask[distributed] with the afe package installed for the Dask figure.
Prints one JSON object. A benchmark, not a test: these machines are noisy, so compare
the ratios measured in one run.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import wave

import numpy as np

REQUESTS = "ratemap,ild,itd,ic"


def write_wav(path, x, fs=44100):
    pcm = np.clip(np.round(x * 32767), -32768, 32767).astype("<i2")
    with wave.open(path, "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(fs)
        w.writeframes(pcm.tobytes())


def binaural(seconds, seed, fs=44100):
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    t = np.arange(n) / fs
    left = 0.2 * np.sin(2 * np.pi * (200 + seed % 500) * t) * (1 + np.sin(2 * np.pi * 3 * t)) + 0.05 * rng.standard_normal(n)
    return np.column_stack([left, 0.7 * np.roll(left, 10)])


def timed(cmd):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--afe", required=True)
    ap.add_argument("--files", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--long-seconds", type=float, default=3600.0)
    ap.add_argument("--skip-dask", action="store_true")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="afe-bench-batch-")
    out = {"files": args.files, "seconds_each": args.seconds, "requests": REQUESTS}
    try:
        corpus = os.path.join(work, "corpus")
        os.makedirs(corpus)
        for k in range(args.files):
            write_wav(os.path.join(corpus, f"f{k:04d}.wav"), binaural(args.seconds, k))
        audio_s = args.files * args.seconds
        wavs = sorted(os.listdir(corpus))
        start = time.perf_counter()
        for name in wavs:
            subprocess.run(
                [args.afe, "extract", os.path.join(corpus, name), "-r", REQUESTS, "--threads", "0",
                 "-o", os.path.join(work, "x.npz")],
                check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )
        out["extract_sequential_s"] = time.perf_counter() - start
        for jobs in (1, 2):
            store = os.path.join(work, f"j{jobs}.zarr")
            out[f"batch_j{jobs}_s"] = timed([args.afe, "batch", corpus, "-r", REQUESTS, "-o", store,
                                             "-j", str(jobs), "--progress", "none"])
        if not args.skip_dask:
            import afe
            import distributed
            with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                          host="127.0.0.1", dashboard_address=None) as cluster, \
                    distributed.Client(cluster) as client:
                start = time.perf_counter()
                afe.batch(corpus, REQUESTS, out=os.path.join(work, "dask.zarr"),
                          executor=client.get_executor(), progress="none")
                out["dask_2_workers_s"] = time.perf_counter() - start
        out["x_real_time_j1"] = audio_s / out["batch_j1_s"]
        out["speedup_j2_over_j1"] = out["batch_j1_s"] / out["batch_j2_s"]
        out["j1_over_extract"] = out["batch_j1_s"] / out["extract_sequential_s"]
        if "dask_2_workers_s" in out:
            out["dask_speed_vs_j2"] = out["batch_j2_s"] / out["dask_2_workers_s"]
        shutil.rmtree(corpus)
        # memory: one long file and four short ones, two workers
        mem = os.path.join(work, "mem")
        os.makedirs(mem)
        block = binaural(60.0, 1)
        with wave.open(os.path.join(mem, "long.wav"), "wb") as w:
            w.setnchannels(2)
            w.setsampwidth(2)
            w.setframerate(44100)
            pcm = np.clip(np.round(block * 32767), -32768, 32767).astype("<i2").tobytes()
            for _ in range(int(args.long_seconds // 60)):
                w.writeframes(pcm)
        for k in range(4):
            write_wav(os.path.join(mem, f"short{k}.wav"), binaural(args.seconds, 100 + k))
        res = subprocess.run(["/usr/bin/time", "-v", args.afe, "batch", mem, "-r", REQUESTS, "-o",
                              os.path.join(work, "mem.zarr"), "-j", "2", "--progress", "none"],
                             check=True, capture_output=True, text=True)
        rss_kb = next(int(line.split()[-1]) for line in res.stderr.splitlines() if "Maximum resident" in line)
        out["long_file_s"] = args.long_seconds
        out["peak_rss_mb_j2_with_long_file"] = rss_kb / 1024
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    sys.exit(main())
