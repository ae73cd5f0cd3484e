#!/usr/bin/env python3
"""Independent Butterworth designs from scipy.signal for afe's tests.

usage: make_butter_fixture.py [OUT.json]   (needs numpy and scipy)

Writes data/butterworth_scipy.json: for a set of (type, order, cut-offs, fs), the
transfer-function coefficients of scipy.signal.butter and the magnitude response at a
few frequencies (scipy.signal.freqz), which tests/butterworth.rs compares with afe.
"""
import json
import os
import sys

import numpy as np
from scipy import signal

DESIGNS = [
    ("low", 1, [150.0], 44100.0),
    ("low", 2, [1000.0], 44100.0),
    ("low", 2, [425.0], 16000.0),
    ("low", 1, [2000.0], 22050.0),
    ("low", 5, [3000.0], 16000.0),
    ("high", 4, [20.0], 44100.0),
    ("high", 3, [500.0], 16000.0),
    ("bandpass", 2, [300.0, 3000.0], 16000.0),
    ("bandpass", 3, [100.0, 8000.0], 44100.0),
    ("stop", 2, [900.0, 1100.0], 16000.0),
    ("stop", 3, [50.0, 5000.0], 44100.0),
]
SCIPY_TYPE = {"low": "lowpass", "high": "highpass", "bandpass": "bandpass", "stop": "bandstop"}


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "data", "butterworth_scipy.json")
    cases = []
    for kind, order, cutoffs, fs in DESIGNS:
        wn = [c / (fs / 2) for c in cutoffs]
        b, a = signal.butter(order, wn if len(wn) > 1 else wn[0], btype=SCIPY_TYPE[kind])
        freqs = [10.0, 100.0, 440.0, 1000.0, 2500.0, 6000.0, fs / 2 * 0.95]
        _, h = signal.freqz(b, a, worN=np.array(freqs), fs=fs)
        cases.append({
            "bw_type": kind, "bw_order": order, "bw_cutoffHz": cutoffs, "fs": fs,
            "b": list(b), "a": list(a),
            "response_hz": freqs, "response_mag": list(np.abs(h)),
        })
    with open(out, "w") as f:
        json.dump({"generator": f"scipy {__import__('scipy').__version__}", "cases": cases}, f, indent=1)
    print(f"{len(cases)} designs written to {out}")


if __name__ == "__main__":
    main(sys.argv)
