#!/usr/bin/env python3
"""Plot the binaural cues of a WAV file with afe: ratemap of both ears, ILD and ITD.

usage: python examples/plot_cues.py [IN.wav] [OUT.png]
       (defaults: data/example_binaural.wav, cues.png; needs afe, numpy, matplotlib)

Every panel has time in seconds on the x axis and the gammatone channels' centre
frequencies in Hz on the y axis.
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import afe  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def main(argv):
    wav = argv[1] if len(argv) > 1 else os.path.join(HERE, "..", "data", "example_binaural.wav")
    png = argv[2] if len(argv) > 2 else "cues.png"
    x, fs = afe.read_wav(wav)
    if x.ndim != 2:
        sys.exit(f"{wav} is mono: ILD and ITD need a binaural (two-channel) file")
    m = afe.Manager(fs, 2)
    for r in ("ratemap", "ild", "itd"):
        m.add_request(r)
    out = m.process_signal(x)
    info = m.info()["ild_mono"]
    cf = np.array(info["cf_hz"])
    n_frames = out["ild_mono"].shape[0]
    hop = 1.0 / info["fs_hz"]  # frame period, s
    window = 0.02  # default window of ratemap, ILD and ITD, s
    # frame j covers [j·hop, j·hop + window): plot it around its centre
    t_edges = np.arange(n_frames + 1) * hop + (window - hop) / 2
    f_edges = np.concatenate([[cf[0] * 0.9], np.sqrt(cf[1:] * cf[:-1]), [cf[-1] * 1.1]])

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, constrained_layout=True)
    panels = [
        (axes[0, 0], 10 * np.log10(out["ratemap_left"] + 1e-12), "Ratemap, left ear (dB)", "viridis"),
        (axes[0, 1], 10 * np.log10(out["ratemap_right"] + 1e-12), "Ratemap, right ear (dB)", "viridis"),
        (axes[1, 0], out["ild_mono"], "ILD, right re left (dB)", "coolwarm"),
        (axes[1, 1], 1e3 * out["itd_mono"], "ITD (ms; negative: right ear lags)", "coolwarm"),
    ]
    for ax, data, title, cmap in panels:
        if cmap == "coolwarm":
            lim = np.nanmax(np.abs(data))
            mesh = ax.pcolormesh(t_edges, f_edges, data.T, cmap=cmap, vmin=-lim, vmax=lim)
        else:
            mesh = ax.pcolormesh(t_edges, f_edges, data.T, cmap=cmap, vmin=np.max(data) - 60)
        ax.set_yscale("log")
        ax.set_title(title)
        ax.set_ylabel("centre frequency (Hz)")
        fig.colorbar(mesh, ax=ax)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(os.path.basename(wav))
    fig.savefig(png, dpi=100)
    print(f"wrote {png}")


if __name__ == "__main__":
    main(sys.argv)
