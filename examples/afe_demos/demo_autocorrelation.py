"""Autocorrelation function (ACF) of the inner-hair-cell signal per frame, channel and lag.

Ports the AFE's ``DEMO_Autocorrelation``: request ``autocorrelation`` on one ear (16
channels, 80 Hz – 8 kHz, Dau inner hair cell, 20-ms Hann windows every 10 ms, no centre
clipping, ``ac_K = 2``) and draw one frame's ACF in every channel. The input is the left
ear of the example WAV, a voice whose fundamental glides from 110 to 180 Hz: every
channel's ACF peaks at the pitch period 1/F0 (and its multiples), and so does their mean,
the summary ACF, from which the ``pitch`` request derives its estimate.

Key numbers: F0 from the highest summary-ACF peak between 2.5 and 12.5 ms (80–400 Hz) in
the frame drawn, its truth, and the median relative error over the voiced frames.

usage: python demo_autocorrelation.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import (
    EXAMPLE_VOICED_S,
    cf_edges,
    erb_axis,
    example_f0_hz,
    frame_times,
    read_example,
    run,
    save_figure,
)

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 16, "ihc_method": "dau",
          "ac_wSizeSec": 0.02, "ac_hSizeSec": 0.01, "ac_clipAlpha": 0.0, "ac_K": 2,
          "ac_wname": "hann"}
FRAME = 50  # frame drawn
F0_RANGE_HZ = (80.0, 400.0)  # pitch search range


def main(outdir: str) -> Dict[str, float]:
    """Computes the ACF, saves ``demo_autocorrelation.png``, returns the F0 estimates."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("autocorrelation", PARAMS)
    acf = m.process_signal(x[:, 0])["autocorrelation_mono"]  # [frame, channel, lag]
    info = m.info()["autocorrelation_mono"]
    lags = np.array(info["lags_s"])
    summary = acf.mean(axis=1)  # [frame, lag]
    search = (lags >= 1 / F0_RANGE_HZ[1]) & (lags <= 1 / F0_RANGE_HZ[0])
    f0 = 1 / lags[search][np.argmax(summary[:, search], axis=1)]
    t = frame_times(acf.shape[0], info["fs_hz"])
    centre = t + PARAMS["ac_wSizeSec"] / 2  # middle of each frame's window
    truth = example_f0_hz(centre)
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])

    fig, axes = plt.subplots(3, 1, figsize=(9, 12), constrained_layout=True)
    lags_ms = 1e3 * lags
    step = lags_ms[1] - lags_ms[0]
    lag_edges = np.append(lags_ms - step / 2, lags_ms[-1] + step / 2)
    mesh = axes[0].pcolormesh(lag_edges, cf_edges(info["cf_hz"]), acf[FRAME], cmap="viridis")
    fig.colorbar(mesh, ax=axes[0], label="normalised autocorrelation")
    erb_axis(axes[0])
    axes[0].set(xlabel="lag (ms)", title=f"ACF per channel, frame {FRAME} ({t[FRAME]:.2f} s)")
    axes[1].plot(lags_ms, summary[FRAME])
    for k in (1, 2):
        axes[1].axvline(1e3 * k / truth[FRAME], color="gray", linestyle="--", linewidth=0.8)
    axes[1].set(xlabel="lag (ms)", ylabel="mean over channels", xlim=(0, lags_ms[-1]),
                title=f"Summary ACF (dashed: true period 1/F0 = {1e3 / truth[FRAME]:.2f} ms and twice it)")
    t_edges = np.append(t, t[-1] + 1 / info["fs_hz"])
    mesh = axes[2].pcolormesh(t_edges, lag_edges, summary.T, cmap="viridis")
    fig.colorbar(mesh, ax=axes[2], label="summary ACF")
    axes[2].plot(centre[voiced], 1e3 / truth[voiced], "w--", label="true period 1/F0")
    axes[2].set(xlabel="time (s)", ylabel="lag (ms)", ylim=(0, 15),
                title="Summary ACF over time")
    axes[2].legend(loc="upper right")
    save_figure(fig, outdir, "demo_autocorrelation")
    return {"f0_frame_hz": float(f0[FRAME]), "f0_frame_truth_hz": float(truth[FRAME]),
            "f0_median_rel_error": float(np.median(np.abs(f0[voiced] / truth[voiced] - 1)))}


if __name__ == "__main__":
    run(main)
