"""The dual-resonance non-linear (DRNL) filterbank next to the linear gammatone.

Ports the AFE's ``DEMO_DRNL``: one channel at 1 kHz (``fb_type = 'drnl'``, CASP
parameters of Jepsen et al. 2008, or ``'gammatone'``), after level scaling (RMS 1 =
100 dB SPL) and the middle-ear filter. The speech of the example WAV is played twice,
first 14 dB softer (10 dB below its level in the file, i.e. about 61 then 75 dB SPL):
the gammatone output steps up by the same 14 dB, the DRNL output by much less, as the
cochlea compresses mid-level sounds. A staircase of 1-kHz tone levels (10 to 100 dB SPL,
100 ms each) gives the input-output functions.

Key numbers: the slope of the input-output function (dB/dB) of the gammatone (truth: 1),
and of the DRNL at low levels (10–30 dB SPL, linear: 1) and mid levels (40–70 dB SPL,
compressive: CASP's exponent 0.25); the speech level step at each output.

usage: python demo_drnl.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import read_example, run, sample_times, save_figure

COMMON = {"pp_bLevelScaling": True, "pp_refSPLdB": 100, "pp_bMiddleEarFiltering": True,
          "pp_middleEarModel": "jepsen", "fb_cfHz": [1000.0]}
BANKS = {"gammatone": dict(COMMON, fb_type="gammatone"), "drnl": dict(COMMON, fb_type="drnl")}
LEVELS_DB_SPL = np.arange(10, 101, 10)
STEP_S = 0.1  # duration of each level of the staircase
EXTRA_GAIN_DB = -10.0  # applied to the speech


def rms_db(x: np.ndarray) -> float:
    """RMS level of ``x`` in dB re 1."""
    return float(20 * np.log10(np.sqrt(np.mean(x**2))))


def main(outdir: str) -> Dict[str, float]:
    """Runs both filterbanks, saves ``demo_drnl.png``, returns the slopes and level steps."""
    x, fs = read_example()
    speech = 10 ** (EXTRA_GAIN_DB / 20) * np.concatenate([x[:, 0] / 5, x[:, 0]])
    n = int(STEP_S * fs)
    t = np.arange(n) / fs
    staircase = np.concatenate([np.sqrt(2) * 10 ** ((level - 100) / 20) * np.sin(2 * np.pi * 1000 * t)
                                for level in LEVELS_DB_SPL])

    io_db, speech_out, steps = {}, {}, {}
    half = len(speech) // 2
    for name, params in BANKS.items():
        y = afe.process(staircase, fs, ["filterbank"], params)["filterbank_mono"][:, 0]
        io_db[name] = np.array([rms_db(y[k * n + n // 2:(k + 1) * n]) for k in range(len(LEVELS_DB_SPL))])
        speech_out[name] = afe.process(speech, fs, ["filterbank"], params)["filterbank_mono"][:, 0]
        steps[name] = rms_db(speech_out[name][half:]) - rms_db(speech_out[name][:half])

    def slope(name: str, lo: float, hi: float) -> float:
        """Least-squares slope of the input-output function between lo and hi dB SPL."""
        keep = (LEVELS_DB_SPL >= lo) & (LEVELS_DB_SPL <= hi)
        return float(np.polyfit(LEVELS_DB_SPL[keep], io_db[name][keep], 1)[0])

    fig, axes = plt.subplots(3, 1, figsize=(9, 11), constrained_layout=True)
    for name, marker in (("gammatone", "s-"), ("drnl", "o-")):
        axes[0].plot(LEVELS_DB_SPL, io_db[name] - io_db[name][0], marker, label=name)
    axes[0].plot(LEVELS_DB_SPL, LEVELS_DB_SPL - LEVELS_DB_SPL[0], "k:", label="slope 1 (linear)")
    axes[0].set(xlabel="input level of the 1-kHz tone (dB SPL)",
                ylabel="output level re the 10-dB SPL input (dB)",
                title="Input-output functions of the 1-kHz channel")
    axes[0].legend()
    axes[0].grid(True)
    ts = sample_times(len(speech), fs)
    for ax, name in zip(axes[1:], ("gammatone", "drnl")):
        ax.plot(ts, speech_out[name], linewidth=0.4)
        ax.set(xlabel="time (s)", ylabel="amplitude", xlim=(0, ts[-1]),
               title=f"{name} output at 1 kHz for the speech, 14 dB softer then louder: "
                     f"step {steps[name]:.1f} dB")
    save_figure(fig, outdir, "demo_drnl")
    return {"gammatone_slope": slope("gammatone", 10, 100),
            "drnl_low_slope": slope("drnl", 10, 30), "drnl_mid_slope": slope("drnl", 40, 70),
            "speech_step_gammatone_db": steps["gammatone"], "speech_step_drnl_db": steps["drnl"]}


if __name__ == "__main__":
    run(main)
