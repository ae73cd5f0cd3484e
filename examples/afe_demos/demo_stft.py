"""Short-time Fourier transform (request ``stft``) next to the ratemap.

Ports the AFE's ``DEMO_STFT``: the ratemap (64 channels, 80 Hz – 8 kHz) and the STFT
(20-ms periodic Hamming windows, hop 10 ms, zero-padded FFT, bins from DC up to below
Nyquist, complex) of the left ear of the example WAV, drawn one above the other: the
STFT resolves the voice's harmonics on a linear frequency axis, the ratemap only the
low ones, on the auditory (ERB) axis.

Key numbers, from a sinusoid of amplitude 0.5 placed exactly on bin 46: the frequency of
the largest bin (from ``info()["stft_..."]["cf_hz"]``; truth: the sinusoid's frequency)
and its magnitude re the amplitude × the window's sum / 2 (truth: 1).

usage: python demo_stft.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import db_power, frame_times, read_example, run, save_figure, tf_image

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 64, "ihc_method": "dau",
          "rm_wSizeSec": 0.02, "rm_hSizeSec": 0.01, "rm_scaling": "magnitude",
          "rm_decaySec": 0.008, "rm_wname": "hann", "stft_wSizeSec": 0.02, "stft_isPruned": True}
TONE_BIN = 46
TONE_AMPLITUDE = 0.5


def main(outdir: str) -> Dict[str, float]:
    """Computes both representations, saves ``demo_stft.png``, returns the tone checks."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("ratemap", PARAMS)
    m.add_request("stft", PARAMS)
    out = m.process_signal(x[:, 0])
    info = m.info()
    bins_hz = np.array(info["stft_mono"]["cf_hz"])

    bin_width = bins_hz[1] - bins_hz[0]
    tone_hz = TONE_BIN * bin_width
    t = np.arange(int(0.5 * fs)) / fs
    spectrum = m.process_signal(TONE_AMPLITUDE * np.sin(2 * np.pi * tone_hz * t))["stft_mono"]
    magnitude = np.abs(spectrum[2:-2]).mean(axis=0)  # frames fully inside the tone
    window = int(2 * round(PARAMS["stft_wSizeSec"] * fs / 2))
    hamming_sum = np.sum(0.54 - 0.46 * np.cos(2 * np.pi * np.arange(window) / window))

    fig, axes = plt.subplots(2, 1, figsize=(9, 9), constrained_layout=True)
    rm_db = 20 * np.log10(np.maximum(out["ratemap_mono"], 1e-9))
    tf_image(fig, axes[0], rm_db, info["ratemap_mono"]["fs_hz"], info["ratemap_mono"]["cf_hz"],
             "level (dB re 1)", vmin=rm_db.max() - 60, vmax=rm_db.max())
    axes[0].set_title("Ratemap (magnitude), left ear of the example WAV")
    stft_db = db_power(np.abs(out["stft_mono"]) ** 2)
    frames = frame_times(stft_db.shape[0], info["stft_mono"]["fs_hz"])
    t_edges = np.append(frames, frames[-1] + 1 / info["stft_mono"]["fs_hz"])
    f_edges = np.append(bins_hz, bins_hz[-1] + bin_width) - bin_width / 2
    mesh = axes[1].pcolormesh(t_edges, f_edges, stft_db.T, vmin=stft_db.max() - 70,
                              vmax=stft_db.max())
    fig.colorbar(mesh, ax=axes[1], label="|STFT|² (dB re 1)")
    axes[1].set(xlabel="time (s)", ylabel="frequency (Hz)", ylim=(0, 4000),
                title="STFT magnitude (linear frequency axis, up to 4 kHz)")
    save_figure(fig, outdir, "demo_stft")
    return {"tone_hz": float(tone_hz), "peak_bin_hz": float(bins_hz[np.argmax(magnitude)]),
            "peak_magnitude_ratio": float(magnitude.max() / (TONE_AMPLITUDE * hamming_sum / 2))}


if __name__ == "__main__":
    run(main)
