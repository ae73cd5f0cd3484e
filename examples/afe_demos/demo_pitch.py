"""Pitch estimation from the summary autocorrelation (request ``pitch``).

Ports the AFE's ``DEMO_Pitch``: request ``pitch`` (16 channels, 80 Hz – 8 kHz, Dau inner
hair cell, ACF without centre clipping, pitch range 80–400 Hz, confidence threshold 0.7,
median filter of order 3) and draw the summary ACF with the raw pitch overlaid in the
lag domain, the confidence with its threshold, and the final pitch. Two inputs of known
F0:

* a harmonic complex of 10 equal-phase harmonics of 200 Hz;
* the left ear of the example WAV, a voice gliding from 110 to 180 Hz.

Key numbers: the median pitch of the complex (truth 200 Hz), and for the voice the
median relative error of the pitch against the glide and the fraction of voiced frames
with a pitch (the others fall below the confidence threshold and are NaN). The faint
noise before the voice starts gets a pitch too, as in the AFE: the threshold is relative
to the largest confidence, and the normalised summary ACF of noise has peaks almost as
high as the voice's.

usage: python demo_pitch.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import EXAMPLE_VOICED_S, example_f0_hz, frame_times, read_example, run, save_figure

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 16, "ihc_method": "dau",
          "ac_wSizeSec": 0.02, "ac_hSizeSec": 0.01, "ac_clipAlpha": 0.0, "ac_K": 2,
          "ac_wname": "hann", "pi_rangeHz": [80, 400], "pi_confThres": 0.7, "pi_medianOrder": 3}
COMPLEX_F0_HZ = 200.0
COMPLEX_HARMONICS = 10


def harmonic_complex(fs: float, duration_s: float = 0.5) -> np.ndarray:
    """Equal-amplitude, sine-phase harmonics 1..COMPLEX_HARMONICS of COMPLEX_F0_HZ."""
    t = np.arange(int(duration_s * fs)) / fs
    k = np.arange(1, COMPLEX_HARMONICS + 1)[:, None]
    return 0.05 * np.sin(2 * np.pi * COMPLEX_F0_HZ * k * t).sum(axis=0)


def main(outdir: str) -> Dict[str, float]:
    """Estimates both pitches, saves ``demo_pitch.png``, returns the errors."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("pitch", PARAMS)
    m.add_request("autocorrelation", PARAMS)  # the ACF the pitch is computed from
    out = m.process_signal(x[:, 0])
    info = m.info()
    features = info["pitch_mono"]["features"]  # ["pitch", "rawPitch", "confidence"]
    pitch, raw, confidence = (out["pitch_mono"][:, features.index(n)]
                              for n in ("pitch", "rawPitch", "confidence"))
    complex_pitch = m.process_signal(harmonic_complex(fs))["pitch_mono"][:, features.index("pitch")]

    t = frame_times(len(pitch), info["pitch_mono"]["fs_hz"])
    centre = t + PARAMS["ac_wSizeSec"] / 2  # middle of each frame's window
    truth = example_f0_hz(centre)
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])
    found = voiced & ~np.isnan(pitch)

    fig, axes = plt.subplots(3, 1, figsize=(9, 11), sharex=True, constrained_layout=True)
    lags_ms = 1e3 * np.array(info["autocorrelation_mono"]["lags_s"])
    summary = out["autocorrelation_mono"].mean(axis=1)
    t_edges = np.append(t, t[-1] + 1 / info["pitch_mono"]["fs_hz"])
    lag_edges = np.append(lags_ms, 2 * lags_ms[-1] - lags_ms[-2]) - (lags_ms[1] - lags_ms[0]) / 2
    mesh = axes[0].pcolormesh(t_edges, lag_edges, summary.T, cmap="viridis")
    fig.colorbar(mesh, ax=axes[0], label="summary ACF")
    with np.errstate(divide="ignore"):
        axes[0].plot(t + 0.5 / info["pitch_mono"]["fs_hz"], 1e3 / raw, "r.", label="1 / raw pitch")
    axes[0].set(ylabel="lag (ms)", ylim=(0, 1e3 / PARAMS["pi_rangeHz"][0]),
                title="Summary ACF and raw pitch in the lag domain")
    axes[0].legend(loc="upper right")
    axes[1].plot(t, confidence, "k.-")
    axes[1].axhline(PARAMS["pi_confThres"] * np.max(confidence), color="r", linestyle="--",
                    label=f"threshold: {PARAMS['pi_confThres']} × maximum")
    axes[1].set(ylabel="confidence (summary-ACF peak)", title="Confidence")
    axes[1].legend(loc="lower right")
    axes[2].plot(t, pitch, "ko", markersize=3, label="pitch")
    axes[2].plot(centre[voiced], truth[voiced], "r--", label="true F0 (110 → 180 Hz glide)")
    axes[2].set(xlabel="time (s)", ylabel="pitch (Hz)", ylim=PARAMS["pi_rangeHz"],
                title="Final pitch (NaN where the confidence is below the threshold)")
    axes[2].legend(loc="upper left")
    save_figure(fig, outdir, "demo_pitch")
    return {
        "complex_pitch_hz": float(np.nanmedian(complex_pitch)),
        "speech_median_rel_error": float(np.median(np.abs(pitch[found] / truth[found] - 1))),
        "speech_voiced_fraction": float(np.sum(found) / np.sum(voiced)),
    }


if __name__ == "__main__":
    run(main)
