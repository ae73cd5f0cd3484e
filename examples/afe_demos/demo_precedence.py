"""Precedence effect: localisation cues that follow the first wavefront (request ``precedence``).

Ports the AFE's ``DEMO_Precedence``: a lead sound is followed 4 ms later by a 3-dB
weaker copy from the mirror-image direction (its ears swapped), as a single reflection
would. The lead is the example WAV (talker on the left: ITD −0.5 ms, ILD −6 dB), so the
lag comes from the right (ITD +0.5 ms). Braasch's lead/lag model (32 channels, 80 Hz –
8 kHz, 20-ms frames every 10 ms, lags of ±1 ms) estimates the lag from each ear's
autocorrelation, removes it, and cross-correlates what remains; the plain interaural
cross-correlation (``crosscorrelation``) sees the sum of both.

The demo draws the precedence ITD and ILD maps, one frame's weighted cross-correlation,
and, per frame, the ITD at the peak of the cross-correlation summed over channels, for
both models. (Single channels scatter: the voice is periodic, with periods of 5.5 to
9 ms, close to the 4-ms lead/lag delay; the sum over channels is robust.)

Key numbers: the median of that per-frame ITD for the precedence model (truth: the
lead's −0.5 ms), and the fraction of frames within a sample of the lead's ITD for the
precedence model and for the plain cross-correlation.

usage: python demo_precedence.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import (
    EXAMPLE_ITD_S,
    EXAMPLE_VOICED_S,
    cf_edges,
    erb_axis,
    frame_times,
    read_example,
    run,
    save_figure,
    tf_image,
)

PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 32,
          "prec_wSizeSec": 0.02, "prec_hSizeSec": 0.01, "prec_maxDelaySec": 0.001}
LAG_DELAY_S = 0.004  # inter-stimulus interval between lead and lag
LAG_GAIN_DB = -3.0
FRAME = 25  # frame whose cross-correlation is drawn


def lead_lag(lead: np.ndarray, fs: float) -> np.ndarray:
    """``lead`` plus a delayed, attenuated copy with its ears swapped."""
    d = int(round(LAG_DELAY_S * fs))
    lag = np.zeros_like(lead)
    lag[d:] = 10 ** (LAG_GAIN_DB / 20) * lead[:-d, ::-1]
    return lead + lag


def summary_itd(ccf: np.ndarray, lags_s: np.ndarray) -> np.ndarray:
    """Per frame, the lag (s) of the peak of the cross-correlation summed over channels."""
    return lags_s[np.argmax(ccf.sum(axis=1), axis=1)]


def main(outdir: str) -> Dict[str, float]:
    """Runs both models on the lead/lag pair, saves ``demo_precedence.png``, returns the ITDs."""
    x, fs = read_example()
    y = lead_lag(x, fs)
    m = afe.Manager(fs, channels=2)
    m.add_request("precedence", PARAMS)
    m.add_request("crosscorrelation", {k: v for k, v in PARAMS.items() if k.startswith("fb_")})
    out = m.process_signal(y)
    info = m.info()
    prec_lags = np.array(info["precedence_cc_mono"]["lags_s"])
    itd_prec = summary_itd(out["precedence_cc_mono"], prec_lags)
    itd_plain = summary_itd(out["crosscorrelation_mono"], np.array(info["crosscorrelation_mono"]["lags_s"]))
    fs_frames = info["precedence_itd_mono"]["fs_hz"]
    t = frame_times(len(itd_prec), fs_frames)
    voiced = (t >= EXAMPLE_VOICED_S[0]) & (t <= EXAMPLE_VOICED_S[1])

    def at_lead(itd: np.ndarray) -> float:
        """Fraction of voiced frames within one sample of the lead's ITD."""
        return float(np.mean(np.abs(itd[voiced] - EXAMPLE_ITD_S) <= 1 / fs))

    cf = info["precedence_itd_mono"]["cf_hz"]
    fig, axes = plt.subplots(4, 1, figsize=(9, 15), constrained_layout=True)
    tf_image(fig, axes[0], 1e3 * out["precedence_itd_mono"], fs_frames, cf,
             "ITD (ms; > 0: right ear leads)", cmap="coolwarm", vmin=-1, vmax=1)
    axes[0].set_title("Precedence ITD (lead from the left, lag from the right 4 ms later)")
    tf_image(fig, axes[1], out["precedence_ild_mono"], fs_frames, cf, "ILD, right re left (dB)",
             cmap="coolwarm", vmin=-12, vmax=12)
    axes[1].set_title("Precedence ILD")
    lags_ms = 1e3 * prec_lags
    step = lags_ms[1] - lags_ms[0]
    mesh = axes[2].pcolormesh(np.append(lags_ms - step / 2, lags_ms[-1] + step / 2), cf_edges(cf),
                              out["precedence_cc_mono"][FRAME], cmap="viridis")
    fig.colorbar(mesh, ax=axes[2], label="weighted cross-correlation")
    axes[2].axvline(1e3 * EXAMPLE_ITD_S, color="w", linestyle="--", linewidth=1)
    erb_axis(axes[2])
    axes[2].set(xlabel="lag (ms; > 0: right ear leads)",
                title=f"Precedence cross-correlation in frame {FRAME} ({t[FRAME]:.2f} s; dashed: lead ITD)")
    axes[3].plot(t, 1e3 * itd_plain, "s", color="0.6", label="plain cross-correlation")
    axes[3].plot(t, 1e3 * itd_prec, "o", markersize=4, label="precedence model")
    for itd, label in ((EXAMPLE_ITD_S, "lead"), (-EXAMPLE_ITD_S, "lag")):
        axes[3].axhline(1e3 * itd, color="gray", linestyle="--", linewidth=0.8)
        axes[3].text(0.01, 1e3 * itd + 0.05, label, color="gray")
    axes[3].set(xlabel="time (s)", ylabel="ITD (ms)", ylim=(-1.2, 1.2),
                title="ITD at the peak of the cross-correlation summed over channels")
    axes[3].legend(loc="upper right")
    save_figure(fig, outdir, "demo_precedence")
    return {"itd_precedence_median_ms": 1e3 * float(np.median(itd_prec[voiced])),
            "frames_at_lead_precedence": at_lead(itd_prec),
            "frames_at_lead_plain": at_lead(itd_plain)}


if __name__ == "__main__":
    run(main)
