"""Interaural time difference (ITD) per frame and gammatone channel.

Ports the AFE's ``DEMO_ITD``: request ``itd`` (the lag of the interaural cross-correlation
maximum, refined by parabolic interpolation; 32 channels, 80 Hz – 8 kHz, Dau inner hair
cell, 20-ms Hann windows every 10 ms) and draw the ITD map. Two inputs with known cues:

* the example WAV, a talker on the left: the right ear lags by 0.5 ms (ITD −0.5 ms; the
  AFE's ITD is positive when the right ear leads);
* white noise whose left ear is delayed by 10 samples at 44.1 kHz (the right ear leads:
  ITD +0.227 ms).

Key numbers: the median ITD of each over the channels from 200 Hz to 1.5 kHz, where the
fine structure is resolved and one period is longer than the ±1.1-ms lag range.

usage: python demo_itd.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import (
    EXAMPLE_ITD_S,
    EXAMPLE_VOICED_S,
    erb_axis,
    frame_times,
    read_example,
    run,
    save_figure,
    symmetric_limit,
    tf_image,
)

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 32, "ihc_method": "dau",
          "cc_wSizeSec": 0.02, "cc_hSizeSec": 0.01, "cc_wname": "hann"}
NOISE_DELAY_SAMPLES = 10  # the noise reaches the left ear this much later
LOW_BAND_HZ = (200.0, 1500.0)  # channels whose ITD the key numbers summarise


def main(outdir: str) -> Dict[str, float]:
    """Computes the ITD of both inputs, saves ``demo_itd.png``, returns the median ITDs."""
    x, fs = read_example()
    rng = np.random.default_rng(2)
    d = NOISE_DELAY_SAMPLES
    source = 0.1 * rng.standard_normal(x.shape[0] + d)
    noise_lr = np.column_stack([source[:-d], source[d:]])  # left[n] = right[n − d]

    m = afe.Manager(fs, channels=2)
    m.add_request("itd", PARAMS)
    itd = m.process_signal(x)["itd_mono"]  # [frame, channel], s
    info = m.info()["itd_mono"]
    itd_noise = afe.process(noise_lr, fs, ["itd"], PARAMS)["itd_mono"]

    cf = np.array(info["cf_hz"])
    low = (cf >= LOW_BAND_HZ[0]) & (cf <= LOW_BAND_HZ[1])
    t = frame_times(itd.shape[0], info["fs_hz"])
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])
    itd_example_ms = 1e3 * float(np.median(itd[voiced][:, low]))
    itd_noise_samples = fs * float(np.median(itd_noise[2:, low]))

    fig, axes = plt.subplots(2, 1, figsize=(9, 8), constrained_layout=True)
    lim = 1e3 * symmetric_limit(itd)
    tf_image(fig, axes[0], 1e3 * itd, info["fs_hz"], cf, "ITD (ms; > 0: right ear leads)",
             cmap="coolwarm", vmin=-lim, vmax=lim)
    axes[0].set_title("ITD of the example WAV (talker on the left)")
    axes[1].plot(cf, 1e3 * np.median(itd[voiced], axis=0), "o-", label="example WAV")
    axes[1].plot(cf, 1e3 * np.median(itd_noise[2:], axis=0), "s-",
                 label=f"noise, left ear delayed {d} samples")
    for truth in (EXAMPLE_ITD_S, d / fs):
        axes[1].axhline(1e3 * truth, color="gray", linestyle="--", linewidth=0.8)
    axes[1].axvspan(*LOW_BAND_HZ, color="0.9", zorder=0, label="channels summarised")
    erb_axis(axes[1], "x")
    axes[1].set(ylabel="median ITD (ms)", title="Median ITD per channel (dashed: truth)")
    axes[1].legend(loc="center right")
    save_figure(fig, outdir, "demo_itd")
    return {"itd_example_ms": itd_example_ms, "itd_noise_samples": itd_noise_samples}


if __name__ == "__main__":
    run(main)
