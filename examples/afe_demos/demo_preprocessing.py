"""Pre-processing of the ear signals (request ``time``): DC removal, pre-emphasis,
automatic gain control (AGC), level scaling and middle-ear filtering.

Ports the AFE's ``DEMO_PreProcessing``: the example WAV is played twice, first 14 dB
(a factor 5) softer, and a slow 0.5-Hz sinusoid of amplitude 0.5 is added to both ears.
The stages are switched on one after the other, each run drawing both ear signals:

1. DC removal (4th-order Butterworth high-pass at 20 Hz) removes the slow sinusoid;
2. pre-emphasis (y[n] = x[n] − 0.97·x[n−1]) tilts the spectrum up;
3. AGC (running RMS over 0.5 s) equalises the two halves: monaural AGC normalises each
   ear on its own and so erases the −6 dB ILD of the example; binaural AGC applies one
   gain to both ears and keeps it;
4. level scaling (``pp_refSPLdB``) multiplies by 10^((100 − pp_refSPLdB)/20), as the AFE;
5. the middle-ear filter (Jepsen et al. 2008), linear phase, 0 dB at its peak.

Key numbers: the residue of the 0.5-Hz sinusoid after DC removal (dB re its RMS, past
the filter's 0.1-s onset transient), the level step between the halves before and after
AGC, the ILD after monaural and binaural AGC, the level-scaling gain, and the middle-ear
filter's peak frequency and delay.

usage: python demo_preprocessing.py [outdir]
"""

from __future__ import annotations

from typing import Any, Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import read_example, run, sample_times, save_figure

DC = {"pp_bRemoveDC": True, "pp_cutoffHzDC": 20}
PRE_EMPHASIS = dict(DC, pp_bPreEmphasis=True, pp_coefPreEmphasis=0.97)
AGC_MONO = dict(PRE_EMPHASIS, pp_bNormalizeRMS=True, pp_intTimeSecRMS=0.5, pp_bBinauralRMS=False)
AGC_BINAURAL = dict(AGC_MONO, pp_bBinauralRMS=True)
LEVEL = dict(AGC_BINAURAL, pp_bLevelScaling=True, pp_refSPLdB=94)
MIDDLE_EAR = dict(LEVEL, pp_bMiddleEarFiltering=True, pp_middleEarModel="jepsen")
STAGES = [("2. ears + 0.5-Hz sinusoid (input)", None), ("3. DC removal", DC),
          ("4. + pre-emphasis", PRE_EMPHASIS), ("5. + monaural AGC", AGC_MONO),
          ("6. + binaural AGC", AGC_BINAURAL), ("7. + level scaling (94 dB)", LEVEL),
          ("8. + middle-ear filter", MIDDLE_EAR)]
DRIFT_HZ, DRIFT_AMPLITUDE = 0.5, 0.5


def time_signal(x: np.ndarray, fs: float, params: Dict[str, Any]) -> np.ndarray:
    """The pre-processed signal ``[samples, ears]`` of ``x`` with ``params``."""
    out = afe.process(x, fs, ["time"], params)
    return np.column_stack([out["time_left"], out["time_right"]]) if x.ndim == 2 else out["time_mono"]


def rms_db(x: np.ndarray) -> float:
    """RMS level of ``x`` in dB re 1."""
    return float(20 * np.log10(np.sqrt(np.mean(x**2))))


def main(outdir: str) -> Dict[str, float]:
    """Runs the stages, saves ``demo_preprocessing.png``, returns the key numbers."""
    x, fs = read_example()
    ears = np.concatenate([x / 5, x])
    t = sample_times(ears.shape[0], fs)
    drift = DRIFT_AMPLITUDE * np.sin(2 * np.pi * DRIFT_HZ * t)
    mixture = ears + drift[:, None]
    outputs = {name: mixture if p is None else time_signal(mixture, fs, p) for name, p in STAGES}

    settled = t >= 0.1
    residue = time_signal(drift, fs, DC)
    half = ears.shape[0] // 2
    steady = slice(half // 2, half)  # second half of each half: past the AGC's settling

    def step_db(y: np.ndarray) -> float:
        """Left-ear level of the loud half re the soft half (dB)."""
        return rms_db(y[half:][steady, 0]) - rms_db(y[:half][steady, 0])

    def ild_db(y: np.ndarray) -> float:
        """Right-ear level re left in the loud half (dB)."""
        return rms_db(y[half:][steady, 1]) - rms_db(y[half:][steady, 0])

    impulse = np.zeros(4096)
    impulse[0] = 1.0
    me = time_signal(impulse, fs, {"pp_bMiddleEarFiltering": True, "pp_middleEarModel": "jepsen"})
    me_gain = np.abs(np.fft.rfft(me))
    me_freqs = np.fft.rfftfreq(len(me), 1 / fs)
    level_gain = time_signal(impulse, fs, {"pp_bLevelScaling": True, "pp_refSPLdB": 94})[0]

    fig, axes = plt.subplots(len(STAGES) + 1, 1, figsize=(9, 16), sharex=True,
                             constrained_layout=True)
    for ax, (title, y) in zip(axes, [("1. ear signals, soft then loud", ears)] + list(outputs.items())):
        ax.plot(t, y[:, 0], linewidth=0.4, label="left")
        ax.plot(t, y[:, 1], linewidth=0.4, label="right", alpha=0.8)
        ax.set(ylabel="amplitude", title=title, xlim=(0, t[-1]))
    axes[0].legend(loc="upper left")
    axes[-1].set_xlabel("time (s)")
    save_figure(fig, outdir, "demo_preprocessing")
    return {
        "dc_residue_db": rms_db(residue[settled]) - rms_db(drift[settled]),
        "level_step_db": step_db(ears),
        "level_step_mono_agc_db": step_db(outputs["5. + monaural AGC"]),
        "ild_mono_agc_db": ild_db(outputs["5. + monaural AGC"]),
        "ild_binaural_agc_db": ild_db(outputs["6. + binaural AGC"]),
        "level_scaling_gain_db": float(20 * np.log10(level_gain)),
        "middle_ear_peak_hz": float(me_freqs[np.argmax(me_gain)]),
        "middle_ear_peak_db": float(20 * np.log10(me_gain.max())),
        "middle_ear_delay_samples": int(np.argmax(np.abs(me))),
    }


if __name__ == "__main__":
    run(main)
