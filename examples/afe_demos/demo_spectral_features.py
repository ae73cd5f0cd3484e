"""Spectral features of the ratemap (request ``spectralFeatures``): 14 descriptors per frame.

Ports the AFE's ``DEMO_SpectralFeatures`` (64 channels, 80 Hz – 8 kHz, power ratemap)
and draws the ratemap with the spectral centroid and roll-off overlaid, and every other
feature against time. The input has known spectra: a 500-Hz tone, a 2-kHz tone and white
noise, 0.4 s each.

Centroid, spread and roll-off come out as fractions of the highest centre frequency of
the filterbank; the demo multiplies them by it (``cf_hz[-1]`` of the ratemap) to get Hz.

Key numbers: the median centroid during each tone (truth: the tone frequency), the
brightness (energy fraction above 1.5 kHz: 0 for the 500-Hz tone, 1 for the 2-kHz one)
and the flatness of a tone (0) and of the noise (well above 0).

usage: python demo_spectral_features.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import db_power, frame_times, run, save_figure, tf_image

FS = 16000.0
SEGMENT_S = 0.4
TONES_HZ = (500.0, 2000.0)
PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 64, "ihc_method": "dau",
          "rm_wSizeSec": 0.02, "rm_hSizeSec": 0.01, "rm_scaling": "power", "rm_decaySec": 0.008,
          "rm_wname": "hann"}
IN_HZ = ("centroid", "spread", "rolloff")  # features given as fractions of the top centre frequency
UNITS = {"hfc": "Hz²", "flux": "dB", "irregularity": "dB", "spread": "Hz"}


def three_segments() -> np.ndarray:
    """A 500-Hz tone, a 2-kHz tone and white noise, SEGMENT_S each."""
    t = np.arange(int(SEGMENT_S * FS)) / FS
    tones = [0.1 * np.sin(2 * np.pi * f * t) for f in TONES_HZ]
    noise = 0.05 * np.random.default_rng(6).standard_normal(t.size)
    return np.concatenate(tones + [noise])


def main(outdir: str) -> Dict[str, float]:
    """Computes the features, saves ``demo_spectral_features.png``, returns the checks."""
    m = afe.Manager(FS, channels=1)
    m.add_request("spectralFeatures", PARAMS)
    m.add_request("ratemap", PARAMS)  # shared: the features' input, and its centre frequencies
    out = m.process_signal(three_segments())
    info = m.info()
    names = info["spectralFeatures_mono"]["features"]
    cf = np.array(info["ratemap_mono"]["cf_hz"])
    features = {n: out["spectralFeatures_mono"][:, i] * (cf[-1] if n in IN_HZ else 1.0)
                for i, n in enumerate(names)}
    t = frame_times(len(features["centroid"]), info["spectralFeatures_mono"]["fs_hz"])
    centre = t + PARAMS["rm_wSizeSec"] / 2  # middle of each frame's window
    segments = [(centre > k * SEGMENT_S + 0.03) & (centre < (k + 1) * SEGMENT_S - 0.03)
                for k in range(3)]  # frames entirely inside one segment

    fig = plt.figure(figsize=(11, 13), constrained_layout=True)
    grid = fig.add_gridspec(5, 3, height_ratios=[2.2, 1, 1, 1, 1])
    ax = fig.add_subplot(grid[0, :])
    level = db_power(out["ratemap_mono"])
    tf_image(fig, ax, level, info["ratemap_mono"]["fs_hz"], cf, "ratemap level (dB re 1)",
             cmap="gray", vmin=level.max() - 70, vmax=level.max())
    for n, style in (("centroid", "r-"), ("rolloff", "c--")):
        ax.plot(t + 0.5 / info["ratemap_mono"]["fs_hz"], features[n], style, label=n)
    ax.legend(loc="upper left")
    ax.set_title("Ratemap of a 500-Hz tone, a 2-kHz tone and white noise, "
                 "with spectral centroid and roll-off")
    others = [n for n in names if n not in ("centroid", "rolloff")]
    for k, n in enumerate(others):
        sub = fig.add_subplot(grid[1 + k // 3, k % 3])
        sub.plot(t, features[n], "k-", linewidth=0.8)
        sub.set_title(n, fontsize=10)
        sub.set_ylabel(UNITS.get(n, "–"), fontsize=8)
        sub.set_xlabel("time (s)", fontsize=8)
        sub.tick_params(labelsize=8)
    save_figure(fig, outdir, "demo_spectral_features")

    def median_in(name: str, segment: int) -> float:
        """Median of feature ``name`` over the frames inside segment ``segment``."""
        return float(np.median(features[name][segments[segment]]))

    return {
        "centroid_500hz_tone_hz": median_in("centroid", 0),
        "centroid_2000hz_tone_hz": median_in("centroid", 1),
        "brightness_500hz_tone": median_in("brightness", 0),
        "brightness_2000hz_tone": median_in("brightness", 1),
        "flatness_tone": median_in("flatness", 0),
        "flatness_noise": median_in("flatness", 2),
    }


if __name__ == "__main__":
    run(main)
