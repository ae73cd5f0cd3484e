"""Interaural level difference (ILD) per frame and gammatone channel.

Ports the AFE's ``DEMO_ILD``: request ``ild`` on a binaural signal (32 channels, 80 Hz –
8 kHz, Dau inner hair cell, 20-ms Hann windows every 10 ms) and draw the ear signals and
the ILD map. Two inputs with known cues:

* the example WAV, a talker on the left whose right-ear signal is 6 dB weaker
  (ILD −6 dB: the AFE's ILD is the right ear's level re the left's);
* white noise reaching the right ear 6 dB louder (ILD +6 dB).

Key numbers: the median ILD of each, over the frames where the signal is on and every
channel.

usage: python demo_ild.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import (
    EXAMPLE_ILD_DB,
    EXAMPLE_VOICED_S,
    erb_axis,
    frame_times,
    read_example,
    run,
    sample_times,
    save_figure,
    symmetric_limit,
    tf_image,
)

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 32, "ihc_method": "dau",
          "ild_wSizeSec": 0.02, "ild_hSizeSec": 0.01, "ild_wname": "hann"}
NOISE_ILD_DB = 6.0  # level of the noise's right ear re its left, dB


def main(outdir: str) -> Dict[str, float]:
    """Computes the ILD of both inputs, saves ``demo_ild.png``, returns the median ILDs."""
    x, fs = read_example()
    rng = np.random.default_rng(1)
    noise = 0.1 * rng.standard_normal(x.shape[0])
    noise_lr = np.column_stack([noise, 10 ** (NOISE_ILD_DB / 20) * noise])

    m = afe.Manager(fs, channels=2)
    m.add_request("ild", PARAMS)
    ild = m.process_signal(x)["ild_mono"]  # [frame, channel], dB, right re left
    info = m.info()["ild_mono"]
    ild_noise = afe.process(noise_lr, fs, ["ild"], PARAMS)["ild_mono"]

    t = frame_times(ild.shape[0], info["fs_hz"])
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])
    median_ild = float(np.median(ild[voiced]))
    median_ild_noise = float(np.median(ild_noise[2:]))

    fig, axes = plt.subplots(3, 1, figsize=(9, 10), constrained_layout=True)
    ts = sample_times(x.shape[0], fs)
    axes[0].plot(ts, x[:, 0], label="left", linewidth=0.6)
    axes[0].plot(ts, x[:, 1], label="right", linewidth=0.6, alpha=0.8)
    axes[0].set(xlabel="time (s)", ylabel="amplitude", title="Ear signals (example WAV)",
                xlim=(ts[0], ts[-1]))
    axes[0].legend(loc="upper right")
    lim = symmetric_limit(ild)
    tf_image(fig, axes[1], ild, info["fs_hz"], info["cf_hz"], "ILD, right re left (dB)",
             cmap="coolwarm", vmin=-lim, vmax=lim)
    axes[1].set_title("ILD of the example WAV (talker on the left)")
    cf = np.array(info["cf_hz"])
    axes[2].plot(cf, np.median(ild[voiced], axis=0), "o-", label="example WAV")
    axes[2].plot(cf, np.median(ild_noise[2:], axis=0), "s-", label="noise, right +6 dB")
    for truth in (EXAMPLE_ILD_DB, NOISE_ILD_DB):
        axes[2].axhline(truth, color="gray", linestyle="--", linewidth=0.8)
    erb_axis(axes[2], "x")
    axes[2].set(ylabel="median ILD (dB)", title="Median ILD per channel (dashed: truth)")
    axes[2].legend()
    save_figure(fig, outdir, "demo_ild")
    return {"median_ild_example_db": median_ild, "median_ild_noise_db": median_ild_noise}


if __name__ == "__main__":
    run(main)
