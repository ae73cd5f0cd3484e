"""Medial olivo-cochlear (MOC) feedback on the DRNL filterbank (request ``moc``).

Ports the AFE's ``DEMO_MOC``: 50-ms tones at 520 Hz and 3980 Hz (2.5-ms ramps, after
50 ms of silence) at 0 to 90 dB SPL go through level scaling, the middle-ear filter and
a one-channel DRNL filterbank tuned to the tone. The ``moc`` request turns the ratemap
level into an attenuation (dB), which is fed back to the DRNL's non-linear path from the
next chunk on, so the signal is streamed in 10-ms chunks (in one call there is no
feedback). The demo draws the MOC attenuation against the tone level and the DRNL
input-output function with and without the feedback. (The AFE demo also applies an
outer-ear filter, which afe does not have; the levels here are at the middle ear.)

Key numbers, per tone: the largest MOC attenuation at each level (truth: 0 dB for
faint tones, growing with the level, never above ``moc_maxAttenuationdB`` = 40 dB), and
the DRNL output reduction by the feedback at 60 dB SPL.

usage: python demo_moc.py [outdir]
"""

from __future__ import annotations

from typing import Dict, Tuple

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import run, sample_times, save_figure

FS = 44100.0
TONES_HZ = (520.0, 3980.0)
LEVELS_DB_SPL = np.arange(0, 91, 10)
SILENCE_S, TONE_S, RAMP_S = 0.05, 0.05, 0.0025
CHUNK = 441  # samples (10 ms)
EXAMPLE_LEVEL_DB_SPL = 40  # level whose waveforms are drawn


def tone(level_db_spl: float, f_hz: float) -> np.ndarray:
    """Silence, then a ramped tone of RMS level ``level_db_spl`` (RMS 1 = 100 dB SPL),
    zero-padded to whole chunks."""
    t = np.arange(int(TONE_S * FS)) / FS
    ramp = np.clip(np.minimum(t, TONE_S - t) / RAMP_S, 0, 1)
    burst = np.sqrt(2) * 10 ** ((level_db_spl - 100) / 20) * np.sin(2 * np.pi * f_hz * t)
    x = np.concatenate([np.zeros(int(SILENCE_S * FS)), burst * np.sin(0.5 * np.pi * ramp) ** 2])
    return np.concatenate([x, np.zeros(-len(x) % CHUNK)])


def params(f_hz: float) -> Dict[str, object]:
    """Pre-processing and one DRNL channel at ``f_hz``."""
    return {"pp_bLevelScaling": True, "pp_bMiddleEarFiltering": True, "fb_type": "drnl",
            "fb_cfHz": [f_hz], "rm_wSizeSec": 0.02, "rm_hSizeSec": 0.01, "rm_decaySec": 0.008}


def with_feedback(x: np.ndarray, f_hz: float) -> Tuple[np.ndarray, np.ndarray]:
    """Streams ``x`` in CHUNK-sample chunks: DRNL output with MOC feedback and the MOC
    attenuation (dB)."""
    m = afe.Manager(FS, channels=1)
    m.add_request("moc", params(f_hz))
    m.add_request("filterbank", params(f_hz))  # the DRNL the MOC feeds back to
    bm, moc = [], []
    for start in range(0, len(x), CHUNK):
        new = m.process_chunk(x[start:start + CHUNK])
        bm.append(new["filterbank_mono"][:, 0])
        moc.append(new["moc_mono"][:, 0])
    return np.concatenate(bm), np.concatenate(moc)


def main(outdir: str) -> Dict[str, float]:
    """Runs every tone, saves ``demo_moc.png``, returns the MOC attenuations."""
    on = slice(int(SILENCE_S * FS), int((SILENCE_S + TONE_S) * FS))

    def rms_db(y: np.ndarray) -> float:
        """RMS level (dB re 1) of ``y`` while the tone is on."""
        return float(20 * np.log10(np.sqrt(np.mean(y[on] ** 2))))

    attenuation, io_open, io_closed, example = {}, {}, {}, {}
    for f in TONES_HZ:
        attenuation[f], io_open[f], io_closed[f] = [], [], []
        for level in LEVELS_DB_SPL:
            x = tone(level, f)
            bm, moc = with_feedback(x, f)
            open_loop = afe.process(x, FS, ["filterbank"], params(f))["filterbank_mono"][:, 0]
            attenuation[f].append(float(moc.max()))
            io_open[f].append(rms_db(open_loop))
            io_closed[f].append(rms_db(bm))
            if level == EXAMPLE_LEVEL_DB_SPL and f == TONES_HZ[0]:
                example = {"without MOC": open_loop, "with MOC": bm}

    fig, axes = plt.subplots(3, 1, figsize=(9, 12), constrained_layout=True)
    for f, style in zip(TONES_HZ, ("o-", "s-")):
        axes[0].plot(LEVELS_DB_SPL, attenuation[f], style, label=f"{f:.0f} Hz")
        axes[1].plot(LEVELS_DB_SPL, io_open[f], style, color="0.6", label=f"{f:.0f} Hz, no MOC")
        axes[1].plot(LEVELS_DB_SPL, io_closed[f], style, label=f"{f:.0f} Hz, with MOC feedback")
    axes[0].axhline(40, color="gray", linestyle="--", linewidth=0.8, label="moc_maxAttenuationdB")
    axes[0].set(xlabel="tone level (dB SPL)", ylabel="largest MOC attenuation (dB)",
                title="MOC activity against the tone level")
    axes[1].set(xlabel="tone level (dB SPL)", ylabel="DRNL output RMS (dB re 1)",
                title="DRNL input-output functions (RMS over the tone)")
    for ax in axes[:2]:
        ax.legend()
        ax.grid(True)
    ts = sample_times(len(example["with MOC"]), FS)
    for name, y in example.items():
        axes[2].plot(ts, y, linewidth=0.6, label=name)
    axes[2].set(xlabel="time (s)", ylabel="amplitude", xlim=(0, ts[-1]),
                title=f"DRNL output, {TONES_HZ[0]:.0f} Hz at {EXAMPLE_LEVEL_DB_SPL} dB SPL, 10-ms chunks")
    axes[2].legend()
    save_figure(fig, outdir, "demo_moc")
    numbers: Dict[str, float] = {}
    at60 = list(LEVELS_DB_SPL).index(60)
    for f in TONES_HZ:
        numbers.update({f"moc_{f:.0f}hz_{level}db_db": a for level, a in zip(LEVELS_DB_SPL, attenuation[f])})
        numbers[f"drnl_reduction_{f:.0f}hz_60db_db"] = io_open[f][at60] - io_closed[f][at60]
    return numbers


if __name__ == "__main__":
    run(main)
