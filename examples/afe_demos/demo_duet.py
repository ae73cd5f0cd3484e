"""DUET histogram: where the sources of a mixture are, in interaural level and delay.

Ports the AFE's ``DEMO_DUET``: request ``ild``, ``itd`` and ``duet`` (Degenerate Unmixing
Estimation Technique, Yilmaz & Rickard 2004: a histogram over time-frequency cells of
the symmetric attenuation α = |R/L| − |L/R| and the delay δ = −angle(R/L)/ω, in samples,
over 0.5-s blocks of 20-ms STFT frames). Two sources that rarely share a time-frequency
cell are mixed:

* the voice of the example WAV (its left ear), reaching the right ear 2 samples later and
  2 dB weaker (α = 10^(−2/20) − 10^(2/20) = −0.46, δ = +2 samples);
* three tones at 4.5, 5.5 and 6.5 kHz reaching the right ear 2 samples earlier and 2 dB
  louder (α = +0.46, δ = −2 samples).

The histogram has one peak per source. (Its δ is positive when the right ear lags,
the opposite sign of the ITD, which is positive when the right ear leads.)

Key numbers: α and δ of the two highest peaks of the block-averaged histogram (truth: the
sources' values above, within one bin).

usage: python demo_duet.py [outdir]
"""

from __future__ import annotations

from typing import Dict, List, Tuple

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import read_example, run, sample_times, save_figure, symmetric_limit, tf_image

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 32}
SOURCES = ((-2.0, 2), (2.0, -2))  # (right re left in dB, right-ear delay in samples)
TONES_HZ = (4500.0, 5500.0, 6500.0)


def place(source: np.ndarray, gain_db: float, delay: int) -> np.ndarray:
    """``[samples, 2]``: ``source`` at the left ear, delayed by ``delay`` samples (early if
    negative) and scaled by ``gain_db`` at the right."""
    right = np.roll(source, delay)
    if delay > 0:
        right[:delay] = 0.0
    elif delay < 0:
        right[delay:] = 0.0
    return np.column_stack([source, 10 ** (gain_db / 20) * right])


def peaks(hist: np.ndarray, alpha: np.ndarray, delta: np.ndarray, count: int) -> List[Tuple[float, float]]:
    """(α, δ) of the ``count`` highest local maxima (3 × 3 neighbourhood) of ``hist``."""
    found = []
    for i in range(1, hist.shape[0] - 1):
        for j in range(1, hist.shape[1] - 1):
            if hist[i, j] > 0 and hist[i, j] == hist[i - 1:i + 2, j - 1:j + 2].max():
                found.append((hist[i, j], alpha[i], delta[j]))
    return [(float(a), float(d)) for _, a, d in sorted(found, reverse=True)[:count]]


def main(outdir: str) -> Dict[str, float]:
    """Mixes the two sources, saves ``demo_duet.png``, returns the histogram peaks."""
    x, fs = read_example()
    t = sample_times(x.shape[0], fs)
    tones = sum(0.05 * np.sin(2 * np.pi * f * t) for f in TONES_HZ)
    mixture = place(x[:, 0], *SOURCES[0]) + place(tones, *SOURCES[1])

    m = afe.Manager(fs, channels=2)
    for request in ("ild", "itd", "duet"):
        m.add_request(request, PARAMS)
    out = m.process_signal(mixture)
    info = m.info()
    alpha = np.array(info["duet_mono"]["alpha"])
    delta = np.array(info["duet_mono"]["delta_samples"])
    hist = np.nanmean(out["duet_mono"], axis=0)  # mean over the 0.5-s blocks
    found = sorted(peaks(hist, alpha, delta, 2))  # by α: voice first

    fig = plt.figure(figsize=(11, 11), constrained_layout=True)
    grid = fig.add_gridspec(3, 2, height_ratios=[0.8, 1, 1.4])
    ax = fig.add_subplot(grid[0, :])
    ax.plot(t, mixture[:, 0], linewidth=0.4, label="left")
    ax.plot(t, mixture[:, 1], linewidth=0.4, label="right", alpha=0.8)
    ax.set(xlabel="time (s)", ylabel="amplitude", xlim=(0, t[-1]),
           title="Mixture: voice (right ear 2 samples late, −2 dB) + tones (2 samples early, +2 dB)")
    ax.legend(loc="upper right")
    for col, (name, scale, label) in enumerate((("ild", 1.0, "ILD, right re left (dB)"),
                                               ("itd", 1e3, "ITD (ms; > 0: right ear leads)"))):
        ax = fig.add_subplot(grid[1, col])
        data = scale * out[f"{name}_mono"]
        lim = min(symmetric_limit(data), 6.0 if name == "ild" else 0.2)
        tf_image(fig, ax, data, info[f"{name}_mono"]["fs_hz"], info[f"{name}_mono"]["cf_hz"], label,
                 cmap="coolwarm", vmin=-lim, vmax=lim)
        ax.set_title(name.upper())
    ax = fig.add_subplot(grid[2, :])
    da, dd = alpha[1] - alpha[0], delta[1] - delta[0]
    mesh = ax.pcolormesh(np.append(delta - dd / 2, delta[-1] + dd / 2),
                         np.append(alpha - da / 2, alpha[-1] + da / 2), hist, cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="histogram weight (maximum 1 per block), block mean")
    for gain_db, d in SOURCES:
        g = 10 ** (gain_db / 20)
        ax.plot(d, g - 1 / g, "r+", markersize=18, markeredgewidth=2)
    ax.set(xlabel="delay δ (samples; > 0: right ear lags)", ylabel="symmetric attenuation α",
           title="DUET histogram (red +: the sources' true α and δ)")
    save_figure(fig, outdir, "demo_duet")
    return {"voice_alpha": found[0][0], "voice_delta_samples": found[0][1],
            "tones_alpha": found[1][0], "tones_delta_samples": found[1][1],
            "alpha_bin": float(da), "delta_bin_samples": float(dd)}


if __name__ == "__main__":
    run(main)
