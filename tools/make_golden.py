#!/usr/bin/env python3
"""Trim the MATLAB AFE oracle into the golden arrays committed under data/golden/.

usage: make_golden.py ORACLE_DIR [OUT_DIR]   (needs numpy and a built `afe` CLI:
       $AFE_CLI, else target/release/afe)

ORACLE_DIR is ../shared/oracle (inputs/, ref/). For every case whose requests afe
implements (the requests `afe list --json` names), every stored signal (except the raw
input) is copied with its first rows only: full-rate signals keep KEEP_FULL_RATE
samples, framed signals KEEP_FRAMES frames.
The arrays keep the oracle's dtype (float32 where the oracle stored float32) and are
deduplicated like the oracle (one file per source array). The input WAV is copied too.
data/golden/cases.json lists each case: requests, non-default parameters, mode, chunk
sizes, and its signals (output key, golden file, full shape).
"""
import json
import os
import shutil
import subprocess
import sys

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
KEEP_FULL_RATE = 4410   # 0.1 s at 44.1 kHz
KEEP_FRAMES = 40        # 0.4 s of frames at 100 Hz


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    oracle = argv[1]
    out = argv[2] if len(argv) > 2 else os.path.join(os.path.dirname(__file__), "..", "data", "golden")
    os.makedirs(out, exist_ok=True)
    cli = os.environ.get("AFE_CLI") or os.path.join(ROOT, "target", "release", "afe")
    listing = json.loads(subprocess.run([cli, "list", "--json"], check=True,
                                        capture_output=True, text=True).stdout)
    supported = {r["name"] for r in listing}
    cases = []
    copied = {}
    for input_name in sorted(os.listdir(os.path.join(oracle, "ref"))):
        ref = os.path.join(oracle, "ref", input_name)
        wav = f"{input_name}.wav"
        shutil.copyfile(os.path.join(oracle, "inputs", wav), os.path.join(out, wav))
        for case in sorted(os.listdir(ref)):
            meta_path = os.path.join(ref, case, "meta.json")
            if not os.path.isfile(meta_path):
                continue
            meta = json.load(open(meta_path))
            if not set(meta["requests"]) <= supported or meta["nondefault_params"].get("fb_type") == "drnl":
                continue
            signals = []
            for sig in meta["signals"]:
                if sig["name"] == "input" or not sig.get("file"):
                    continue
                src = sig["file"]
                if src not in copied:
                    arr = np.load(os.path.join(ref, src))
                    rows = KEEP_FULL_RATE if sig["fs_hz"] == meta["input_fs_hz"] else KEEP_FRAMES
                    dst = f"{input_name}/{src}"
                    os.makedirs(os.path.join(out, os.path.dirname(dst)), exist_ok=True)
                    np.save(os.path.join(out, dst), arr[:rows])
                    copied[src] = dst
                signals.append({
                    "key": f"{sig['name']}_{sig['channel']}",
                    "file": copied[src],
                    "shape": sig["shape"],
                })
            cases.append({
                "input": wav,
                "case": case,
                "requests": meta["requests"],
                "nondefault_params": meta["nondefault_params"],
                "mode": meta["mode"],
                "chunk_sizes_used": meta["chunk_sizes_used"],
                "signals": signals,
            })
    with open(os.path.join(out, "cases.json"), "w") as f:
        json.dump(cases, f, indent=1)
    print(f"{len(cases)} cases, {len(copied)} arrays in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
