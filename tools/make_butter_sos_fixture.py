#!/usr/bin/env python3
"""Second-order-section Butterworth designs from scipy.signal for afe's tests.

usage: make_butter_sos_fixture.py [OUT.json]   (needs numpy and scipy)

Writes data/butterworth_scipy_sos.json: for a grid of designs (every type, orders 1 to
32, the accepted maximum, cut-offs from 1 Hz to 1 Hz below Nyquist, wide band-passes and
band-stops reaching close to 0 and to Nyquist, narrow ones), scipy.signal.butter's design
as second-order sections (output='sos'), its magnitude response at a few frequencies
(sosfreqz) and the first samples of its impulse response (sosfilt), which
tests/butterworth.rs compares with afe's `butterworth` request.
"""
import json
import os
import sys

import numpy as np
from scipy import signal

IMPULSE_SAMPLES = 64
ONE_CUTOFF_ORDERS = [1, 2, 3, 4, 5, 8, 12, 16, 24, 32]
BAND_ORDERS = [1, 2, 3, 4, 8, 12, 16, 24, 32]
SCIPY_TYPE = {"low": "lowpass", "high": "highpass", "bandpass": "bandpass", "stop": "bandstop"}


def designs():
    for fs, orders in ((44100.0, ONE_CUTOFF_ORDERS), (16000.0, [2, 8, 32])):
        for kind in ("low", "high"):
            for order in orders:
                for cutoff in (1.0, 20.0, 1000.0, 0.45 * fs, fs / 2 - 1.0):
                    yield kind, order, [cutoff], fs
    fs = 44100.0
    bands = [
        [20.0, 20000.0],
        [5.0, 22000.0],
        [1.0, 22049.0],
        [1.0, 100.0],
        [21900.0, 22049.0],
        [45.0, 55.0],
        [1000.0, 1001.0],
        [300.0, 3000.0],
        [100.0, 8000.0],
    ]
    for kind in ("bandpass", "stop"):
        for order in BAND_ORDERS:
            for band in bands:
                yield kind, order, band, fs


def response_frequencies(cutoffs, fs):
    """Log-spaced from 0.5 Hz to just below Nyquist, and each cut-off and its neighbours."""
    freqs = list(np.geomspace(0.5, fs / 2 * 0.9999, 30))
    for c in cutoffs:
        freqs += [c * 0.9, c, min(c * 1.1, fs / 2 * 0.9999)]
    return sorted(freqs)


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "data", "butterworth_scipy_sos.json")
    cases = []
    for kind, order, cutoffs, fs in designs():
        wn = [c / (fs / 2) for c in cutoffs]
        sos = signal.butter(order, wn if len(wn) > 1 else wn[0], btype=SCIPY_TYPE[kind],
                            output="sos")
        freqs = response_frequencies(cutoffs, fs)
        _, h = signal.sosfreqz(sos, worN=np.array(freqs), fs=fs)
        impulse = np.zeros(IMPULSE_SAMPLES)
        impulse[0] = 1.0
        cases.append({
            "bw_type": kind, "bw_order": order, "bw_cutoffHz": cutoffs, "fs": fs,
            "sos": [list(s) for s in sos],
            "response_hz": freqs, "response_mag": list(np.abs(h)),
            "impulse": list(signal.sosfilt(sos, impulse)),
        })
    with open(out, "w") as f:
        json.dump({"generator": f"scipy {__import__('scipy').__version__}", "cases": cases}, f)
    print(f"{len(cases)} designs written to {out}")


if __name__ == "__main__":
    main(sys.argv)
