"""Writes data/middle_ear_fir2.json: an independent reference for the middle-ear FIRs.

A second reading of MATLAB's `fir2` (spec 01-P14) and of the middle-ear designs
(spec 10-preProc), written from the spec text in NumPy alone (no SciPy, no afe code), so
that a slip in the Rust design (afe-core/src/fir2.rs, processors/src/middle_ear.rs) shows
up as a disagreement instead of being copied into both. The oracle cannot serve: it ran
Octave's `fir2`, which differs from MATLAB's by 2.3 % of the peak tap (spec N13).

Contents: plain `fir2` designs (a low-pass with strictly increasing breakpoints, one with
a repeated breakpoint, i.e. a jump ramped over `lap` grid points, and an odd order), and
the `jepsen` and `lopezpoveda` taps at 16, 44.1 and 48 kHz. The Rust tests compare them
to 1e-12 of the largest tap.

Run: python3 tools/make_middle_ear_fixture.py  (NumPy only)
"""
import json
import math
import os

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def hamming_symmetric(n):
    """MATLAB's hamming(n): 0.54 - 0.46 cos(2 pi k / (n - 1))."""
    k = np.arange(n)
    return 0.54 - 0.46 * np.cos(2 * np.pi * k / (n - 1))


def matlab_fir2(order, f, m):
    """MATLAB's fir2(order, f, m) with its default grid, ramp and window (spec 01-P14)."""
    nn = order + 1
    npt = 512 if nn < 1024 else 2 ** math.ceil(math.log2(nn))
    lap = int(npt / 25)
    points = npt + 1
    grid = np.zeros(points)
    # MATLAB's 1-based indices are kept as such; grid[j - 1] is H(j).
    start = 1
    grid[0] = m[0]
    for i in range(len(f) - 1):
        if f[i + 1] == f[i]:
            start = math.ceil(start - lap / 2)
            end = start + lap
        else:
            end = int(f[i + 1] * points)  # fix() of a positive number
        for j in range(start, end + 1):
            if 1 <= j <= points:
                inc = 0.0 if start == end else (j - start) / (end - start)
                grid[j - 1] = inc * m[i + 1] + (1 - inc) * m[i]
        start = end + 1
    delay = (nn - 1) / 2
    shift = np.exp(-1j * np.pi * delay * np.arange(points) / (points - 1))
    half = grid * shift
    spectrum = np.concatenate([half, np.conj(half[-2:0:-1])])
    taps = np.real(np.fft.ifft(spectrum))[:nn]
    return taps * hamming_symmetric(nn)


JEPSEN = [
    (50, 48046.39731), (100, 24023.19865), (200, 12011.59933), (400, 6005.799663),
    (600, 3720.406871), (800, 2866.404385), (1000, 3363.247811), (1200, 4379.228921),
    (1400, 4804.639731), (1600, 5732.808769), (1800, 6228.236688), (2000, 7206.959596),
    (2200, 9172.494031), (2400, 9554.681282), (2600, 10779.64042), (2800, 12011.59933),
    (3000, 14013.53255), (3500, 16015.46577), (4000, 18017.39899), (4500, 23852.82136),
    (5000, 21020.29882), (5500, 22931.23508), (6000, 28027.06509), (6500, 28745.70779),
    (7000, 32098.9), (7500, 34504.4), (8000, 36909.9), (8500, 39315.4), (9000, 41720.9),
    (9500, 44126.4), (10000, 46531.9),
]

GOODE = [
    (400, 0.19953), (600, 0.22909), (800, 0.21878), (1000, 0.15136), (1200, 0.10000),
    (1400, 0.07943), (1600, 0.05754), (1800, 0.04365), (2000, 0.03311), (2200, 0.02754),
    (2400, 0.02188), (2600, 0.01820), (2800, 0.01445), (3000, 0.01259), (3500, 0.00900),
    (4000, 0.00700), (4500, 0.00457), (5000, 0.00500), (5500, 0.00400), (6000, 0.00300),
    (6500, 0.00275),
]
LOPEZ_LOW = [(100, 1.181e-9), (200, 2.363e-9)]
LOPEZ_HIGH = [
    (7000, 8.705e-10), (7500, 8.000e-10), (8000, 7.577e-10), (8500, 7.168e-10),
    (9000, 6.781e-10), (9500, 6.240e-10), (10000, 6.000e-10),
]


def jepsen(fs):
    """Spec 10-preProc, 'jepsen': inverted stapes table, fir2(512), peak normalisation."""
    rows = [(f, v) for f, v in JEPSEN if fs > 20000 or f < fs / 2]
    f = [0.0] + [fr * (2 / fs) for fr, _ in rows] + [1.0]
    m = [0.0] + [1 / v for _, v in rows] + [0.0]
    b = matlab_fir2(512, f, m)
    peak = np.abs(np.fft.fft(b)).max()
    return b / peak * 1e-8 * 10 ** (104 / 20)


def analytic(x):
    """MATLAB's hilbert(x) for a real vector (spec 01-P5)."""
    n = len(x)
    h = np.zeros(n)
    h[0] = 1
    if n % 2 == 0:
        h[n // 2] = 1
        h[1 : n // 2] = 2
    else:
        h[1 : (n + 1) // 2] = 2
    return np.fft.ifft(np.fft.fft(x) * h)


def lopezpoveda(fs):
    """Spec 10-preProc, 'lopezpoveda': velocity table, fir2(512)/20e-6, minimum phase."""
    rows = list(LOPEZ_LOW)
    rows += [(f, d * 1e-6 * 2 * np.pi * f * 10 ** (-104 / 20) * math.sqrt(2)) for f, d in GOODE]
    rows += LOPEZ_HIGH
    nyquist = fs / 2
    if fs <= 20000:
        rows = [(f, v) for f, v in rows if f < nyquist]
    else:
        for _ in range(math.floor((nyquist - 10000) / 1000)):
            f, v = rows[-1]
            rows.append((f + 1000, v / 1.1))
    last_f, last_v = rows[-1]
    if last_f != nyquist:
        rows.append((nyquist, last_v / (1 + (nyquist - last_f) * 0.1 / 1000)))
    f = [0.0] + [fr * 2 / fs for fr, _ in rows]
    m = [0.0] + [v for _, v in rows]
    b = matlab_fir2(512, f, m) / 20e-6
    spectrum = np.fft.fft(b)
    phase = np.imag(analytic(np.log(np.abs(spectrum))))
    return np.real(np.fft.ifft(np.abs(spectrum) * np.exp(-1j * phase)))


def main():
    designs = [
        {"order": 64, "f": [0.0, 0.3, 0.4, 1.0], "m": [1.0, 1.0, 0.0, 0.0]},
        {"order": 100, "f": [0.0, 0.5, 0.5, 1.0], "m": [1.0, 1.0, 0.0, 0.0]},
        {"order": 33, "f": [0.0, 0.2, 0.6, 1.0], "m": [0.0, 1.0, 0.5, 0.0]},
    ]
    for d in designs:
        d["taps"] = matlab_fir2(d["order"], d["f"], d["m"]).tolist()
    middle_ear = []
    for fs in (16000.0, 44100.0, 48000.0):
        middle_ear.append({"model": "jepsen", "fs_hz": fs, "taps": jepsen(fs).tolist()})
        middle_ear.append({"model": "lopezpoveda", "fs_hz": fs, "taps": lopezpoveda(fs).tolist()})
    out = {
        "about": "independent NumPy reading of MATLAB fir2 and the middle-ear designs; "
        "tools/make_middle_ear_fixture.py",
        "fir2": designs,
        "middle_ear": middle_ear,
    }
    path = os.path.join(ROOT, "data", "middle_ear_fir2.json")
    with open(path, "w") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
