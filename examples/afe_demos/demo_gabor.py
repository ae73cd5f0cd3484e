"""Spectro-temporal Gabor filterbank features (request ``gabor``).

Ports the AFE's ``DEMO_GaborFeatures``: a ratemap with the ETSI-like 23 channels from
124 Hz to 3657 Hz (25-ms windows every 10 ms) is log-compressed and filtered with the
2-D Gabor filters of Schädler, Meyer & Kollmeier (2012); the outputs of selected
channels form the feature vector. The demo draws the ratemap and the features of the
left ear of the example WAV.

Key numbers: the number of features (truth: 311, the well-known dimension of these
features for 23 channels) and the mean and standard deviation of the features over the
signal (the processor normalises each feature to zero mean and unit variance over the
chunk it is given, here the whole signal).

usage: python demo_gabor.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import db_power, frame_times, read_example, run, save_figure, tf_image

PARAMS = {"fb_type": "gammatone", "fb_lowFreqHz": 124, "fb_highFreqHz": 3657,
          "fb_nChannels": 23, "rm_wSizeSec": 0.025, "rm_hSizeSec": 0.01, "rm_decaySec": 0.008}


def main(outdir: str) -> Dict[str, float]:
    """Computes the features, saves ``demo_gabor.png``, returns their count and moments."""
    x, fs = read_example()
    m = afe.Manager(fs, channels=1)
    m.add_request("gabor", PARAMS)
    m.add_request("ratemap", PARAMS)  # the gabor processor's input
    out = m.process_signal(x[:, 0])
    info = m.info()
    features = out["gabor_mono"]  # [frame, feature]

    fig, axes = plt.subplots(2, 1, figsize=(9, 9), constrained_layout=True)
    level = db_power(out["ratemap_mono"])
    tf_image(fig, axes[0], level, info["ratemap_mono"]["fs_hz"], info["ratemap_mono"]["cf_hz"],
             "level (dB re 1)", vmin=level.max() - 80, vmax=level.max())
    axes[0].set_title("Ratemap, 23 channels (left ear of the example WAV)")
    t = frame_times(features.shape[0], info["gabor_mono"]["fs_hz"])
    t_edges = np.append(t, t[-1] + 1 / info["gabor_mono"]["fs_hz"])
    mesh = axes[1].pcolormesh(t_edges, np.arange(features.shape[1] + 1) + 0.5, features.T,
                              cmap="RdBu_r", vmin=-3, vmax=3)
    fig.colorbar(mesh, ax=axes[1], label="normalised feature value (standard deviations)")
    axes[1].set(xlabel="time (s)", ylabel="feature number",
                title=f"Gabor filterbank features ({features.shape[1]} per frame)")
    save_figure(fig, outdir, "demo_gabor")
    return {"n_features": int(features.shape[1]),
            "max_abs_feature_mean": float(np.max(np.abs(features.mean(axis=0)))),
            "median_feature_std": float(np.median(features.std(axis=0)))}


if __name__ == "__main__":
    run(main)
