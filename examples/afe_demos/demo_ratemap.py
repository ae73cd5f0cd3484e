"""Ratemap: the smoothed, framed inner-hair-cell envelope, an auditory spectrogram.

Ports the AFE's ``DEMO_Ratemap``: request ``ratemap`` on one ear (64 channels, 80 Hz –
8 kHz, Dau inner hair cell, 20-ms Hann windows every 10 ms, 8-ms leaky integrator,
magnitude scaling) and draw the ratemap and the inner-hair-cell signal it is computed
from. The input is the left ear of the example WAV, whose voice has spectral-envelope
resonances ("formants") at 500, 1500 and 2500 Hz.

Key numbers: the centre frequencies of the peaks of the long-term ratemap spectrum
nearest to each formant (truth: within one ERB of it).

usage: python demo_ratemap.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import (
    EXAMPLE_FORMANTS_HZ,
    EXAMPLE_VOICED_S,
    erb_axis,
    frame_times,
    read_example,
    run,
    save_figure,
    tf_image,
    waveplot,
)

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 64, "ihc_method": "dau",
          "rm_wSizeSec": 0.02, "rm_hSizeSec": 0.01, "rm_scaling": "magnitude",
          "rm_decaySec": 0.008, "rm_wname": "hann"}
EXCERPT_S = (0.40, 0.43)  # inner-hair-cell excerpt drawn as waveforms


def main(outdir: str) -> Dict[str, float]:
    """Computes the ratemap, saves ``demo_ratemap.png``, returns the formant peaks (Hz)."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("ratemap", PARAMS)
    m.add_request("innerhaircell", PARAMS)  # shares the ratemap's filterbank and IHC
    out = m.process_signal(x[:, 0])
    info = m.info()["ratemap_mono"]
    cf = np.array(info["cf_hz"])
    level_db = 20 * np.log10(np.maximum(out["ratemap_mono"], 1e-9))  # magnitude: 20·log10

    t = frame_times(level_db.shape[0], info["fs_hz"])
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])
    spectrum_db = 20 * np.log10(np.mean(out["ratemap_mono"][voiced], axis=0))
    peaks = [c for c in range(1, len(cf) - 1)
             if spectrum_db[c] > spectrum_db[c - 1] and spectrum_db[c] >= spectrum_db[c + 1]]
    formant_peaks = [float(cf[min(peaks, key=lambda c: abs(cf[c] - f))]) for f in EXAMPLE_FORMANTS_HZ]

    fig = plt.figure(figsize=(9, 11), constrained_layout=True)
    grid = fig.add_gridspec(3, 1, height_ratios=[1.2, 1, 1.2])
    ax = fig.add_subplot(grid[0])
    top = level_db.max()
    tf_image(fig, ax, level_db, info["fs_hz"], cf, "level (dB re 1)", vmin=top - 60, vmax=top)
    ax.set_title("Ratemap of the left ear (magnitude scaling)")
    ax = fig.add_subplot(grid[1])
    ax.plot(cf, spectrum_db - spectrum_db.max(), "o-", markersize=3)
    for f, p in zip(EXAMPLE_FORMANTS_HZ, formant_peaks):
        ax.axvline(f, color="gray", linestyle="--", linewidth=0.8)
        ax.plot(p, spectrum_db[list(cf).index(p)] - spectrum_db.max(), "rv")
    erb_axis(ax, "x")
    ax.set(ylabel="mean level (dB re max)",
           title="Long-term ratemap spectrum (dashed: formants of the source; ▼ peaks found)")
    ax = fig.add_subplot(grid[2])
    a, b = (int(round(s * fs)) for s in EXCERPT_S)
    every = 4  # one channel in four, for legible traces
    waveplot(ax, out["innerhaircell_mono"][a:b, ::every], fs, cf[::every], t0_s=a / fs, zoom=3)
    ax.set_title(f"Inner-hair-cell signal, one channel in {every}")
    save_figure(fig, outdir, "demo_ratemap")
    return {f"formant_peak_{int(f)}_hz": p for f, p in zip(EXAMPLE_FORMANTS_HZ, formant_peaks)}


if __name__ == "__main__":
    run(main)
