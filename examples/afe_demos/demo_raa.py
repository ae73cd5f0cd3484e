"""Room Acoustic Analyzer (``afe.raa``, the AFE's ``afeRAA``): how reverberant, clear,
wide and enveloping a recorded room sounds.

Ports the AFE's ``DEMO_RAA``: van Dorp Schuitman's model splits Psi, the adaptation-loop
output low-passed over 20 ms, per ear and band into a direct (foreground) stream, its
peaks and dips that last at least ``T_min`` (63.1 ms), and a reverberant (background)
stream, the rest; the streams' levels and the fluctuations of the interaural time
difference give four predictors, each unscaled and scaled to 0..1 by a sigmoid:
reverberance, clarity, apparent source width (ASW) and listener envelopment (LEV). The
input is ``data/raa_speech_16k.wav`` (the AFE demo's room recording is not
redistributable): 3 s of speech at 16 kHz in a synthetic room, RT60 0.6 s, the source to
the right. The figure draws the ear signals, Psi of the left ear in the band at about
1.4 kHz (the band the AFE demo draws) with its direct and reverberant streams, and the
scaled predictors.

Key numbers: the predictors, and their largest relative difference from the AFE's own
``afeRAA`` run on the same file under GNU Octave (``data/oracle_raa/``; truth: below
1e-6); the share of samples in the direct streams.

usage: python demo_raa.py [outdir]
"""

from __future__ import annotations

import os
from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import REPO_ROOT, run, save_figure

RAA_WAV = os.path.join(REPO_ROOT, "data", "raa_speech_16k.wav")
REFERENCE = os.path.join(REPO_ROOT, "data", "oracle_raa", "raa_speech_16k.npz")
BAND_HZ = 1430.0  # the band the AFE demo draws (its 14th of 16)
SCALED = (("sREV", "reverberance"), ("sClar", "clarity"), ("sASW", "apparent\nsource width"),
          ("sLEV", "listener\nenvelopment"))


def main(outdir: str) -> Dict[str, float]:
    """Runs the RAA, saves ``demo_raa.png``, returns the predictors and checks."""
    x, fs = afe.read_wav(RAA_WAV)
    par, psi = afe.raa(x, fs)
    ref = np.load(REFERENCE)
    rel = max(abs(par[k] - float(ref[f"par_{k}"])) / abs(float(ref[f"par_{k}"])) for k in par)

    band = int(np.argmin(np.abs(psi["f"] - BAND_HZ)))
    t = psi["t_psi"]
    fig, axes = plt.subplots(5, 1, figsize=(9, 13), constrained_layout=True)
    axes[0].plot(t, x[:, 0], linewidth=0.4, label="left")
    axes[0].plot(t, x[:, 1], linewidth=0.4, alpha=0.7, label="right")
    axes[0].set(xlabel="time (s)", ylabel="amplitude", xlim=(t[0], t[-1]), title="Input signal")
    axes[0].legend(loc="upper right")
    cf = psi["f"][band]
    for ax, key, what in ((axes[1], "PsiL", "adaptation-loop output, low-passed"),
                          (axes[2], "PsiLdir", "direct stream"),
                          (axes[3], "PsiLrev", "reverberant stream")):
        ax.plot(t, psi[key][:, band], linewidth=0.6)
        ax.set(xlabel="time (s)", ylabel="MU", xlim=(t[0], t[-1]),
               title=f"{key}: {what}, left ear, {cf:.0f}-Hz band")
    names = [label for _, label in SCALED]
    values = [par[k] for k, _ in SCALED]
    bars = axes[4].bar(names, values, color="tab:blue")
    for bar, (k, _) in zip(bars, SCALED):
        axes[4].text(bar.get_x() + bar.get_width() / 2, bar.get_height() + 0.02,
                     f"{k} {par[k]:.3f}", ha="center")
    axes[4].set(ylim=(0, 1.15), ylabel="scaled predictor (0..1)",
                title=f"Predictors (unscaled: reverberance BL {par['BL']:.1f} MU, clarity "
                      f"{par['pClar']:.2f}, ASW {par['pASW']:.2f}, LEV {par['pLEV']:.2f})")
    save_figure(fig, outdir, "demo_raa")
    return {
        **par,
        "max_par_rel_error_vs_afe": float(rel),
        "direct_fraction_left": float(np.mean(psi["PsiLdir"] != 0)),
        "direct_fraction_right": float(np.mean(psi["PsiRdir"] != 0)),
    }


if __name__ == "__main__":
    run(main)
