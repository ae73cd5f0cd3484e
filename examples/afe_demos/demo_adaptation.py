"""Adaptation loops (request ``adaptation``): the auditory nerve's response to onsets and
steady sounds.

Ports the AFE's ``DEMO_Adaptation``: five feedback loops with time constants from 5 to
500 ms (Dau et al. 1996) divide the inner-hair-cell signal by its own recent history. A
sudden sound gives a large onset response that decays to a much smaller steady state,
and its end an undershoot below the resting output; the steady state grows about
linearly with the level in dB (each loop takes roughly a square root, five loops a
32nd root: nearly logarithmic compression). The input is a 4-kHz tone burst at 40, 60
and 80 dB SPL (RMS 1 = 100 dB SPL) with silences in between, into one channel at
4 kHz (high enough for the inner hair cell to keep only the envelope); the demo also
draws the adaptation output of the example WAV in 16 channels, with the AFE demo's
``adpt_model = 'adt_vandorpschuitman'``.

Key numbers: the steady-state output (model units) at each level, the ratio of the two
20-dB steps (truth: near 1 for a logarithmic response), the smallest onset-to-steady
ratio (well above 1) and whether every offset undershoots the resting output.

usage: python demo_adaptation.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import read_example, run, sample_times, save_figure, waveplot

LEVELS_DB_SPL = (40, 60, 80)
BURST_S, GAP_S = 0.4, 0.3
TONE_HZ = 4000.0
SPEECH_PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 16,
                 "adpt_model": "adt_vandorpschuitman"}


def bursts(fs: float) -> np.ndarray:
    """Silence, then one tone burst per level, each followed by silence."""
    t = np.arange(int(BURST_S * fs)) / fs
    gap = np.zeros(int(GAP_S * fs))
    parts = [gap]
    for level in LEVELS_DB_SPL:
        parts += [np.sqrt(2) * 10 ** ((level - 100) / 20) * np.sin(2 * np.pi * TONE_HZ * t), gap]
    return np.concatenate(parts)


def main(outdir: str) -> Dict[str, float]:
    """Runs both inputs, saves ``demo_adaptation.png``, returns the response checks."""
    x, fs = read_example()
    tones = bursts(fs)
    y = afe.process(tones, fs, ["adaptation"], {"fb_cfHz": [TONE_HZ]})["adaptation_mono"][:, 0]
    m = afe.Manager(fs, channels=1)
    m.add_request("adaptation", SPEECH_PARAMS)
    speech = m.process_signal(x[:, 0])["adaptation_mono"]
    cf = m.info()["adaptation_mono"]["cf_hz"]

    t = sample_times(len(y), fs)
    steady, onset_ratio, undershoot = [], [], []
    for k in range(len(LEVELS_DB_SPL)):
        on = GAP_S + k * (BURST_S + GAP_S)
        burst = y[(t >= on) & (t < on + BURST_S)]
        steady.append(float(np.mean(burst[-int(0.1 * fs):])))
        onset_ratio.append(float(burst[:int(0.03 * fs)].max() / steady[-1]))
        rest = float(np.mean(y[(t >= on - 0.05) & (t < on)]))
        undershoot.append(float(y[(t >= on + BURST_S) & (t < on + BURST_S + 0.05)].min()) < rest)

    fig, axes = plt.subplots(3, 1, figsize=(9, 11), constrained_layout=True)
    axes[0].plot(t, tones, linewidth=0.5)
    levels = ", ".join(str(level) for level in LEVELS_DB_SPL)
    axes[0].set(xlabel="time (s)", ylabel="amplitude (1 = 100 dB SPL)", xlim=(0, t[-1]),
                title=f"{TONE_HZ / 1000:g}-kHz tone bursts at {levels} dB SPL")
    axes[1].plot(t, y, linewidth=0.8)
    for k, level in enumerate(LEVELS_DB_SPL):
        on = GAP_S + k * (BURST_S + GAP_S)
        axes[1].hlines(steady[k], on, on + BURST_S, color="r", linestyle="--")
        axes[1].text(on + 0.02, -120, f"{level} dB SPL: {steady[k]:.0f}", color="r")
    axes[1].set(xlabel="time (s)", ylabel="adaptation output (model units)", xlim=(0, t[-1]),
                ylim=(min(-50.0, float(y.min()) * 1.1), 400),
                title=f"Adaptation output in the {TONE_HZ / 1000:g}-kHz channel "
                      "(onsets clipped; dashed: steady state)")
    waveplot(axes[2], speech, fs, cf, zoom=2)
    axes[2].set_title("Adaptation output of the example WAV (van Dorp Schuitman model)")
    save_figure(fig, outdir, "demo_adaptation")
    return {
        **{f"steady_{level}db_mu": s for level, s in zip(LEVELS_DB_SPL, steady)},
        "step_ratio": (steady[2] - steady[1]) / (steady[1] - steady[0]),
        "min_onset_ratio": min(onset_ratio),
        "offsets_undershoot": bool(all(undershoot)),
    }


if __name__ == "__main__":
    run(main)
