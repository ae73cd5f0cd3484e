"""Amplitude-modulation spectrogram (request ``amsFeatures``).

Ports the AFE's ``DEMO_AMS``: the inner-hair-cell envelope of each gammatone channel
(23 channels, 80 Hz – 8 kHz) is split into modulation bands, either by 15 IIR band-pass
filters on a logarithmic axis from 4 to 1024 Hz (``ams_fbType = 'log'``; the lowest
band is a low-pass and carries the envelope's mean) or by 15 triangles 64 Hz apart on a
linear axis (``'lin'``), framed into 32-ms windows every 16 ms. The input has known
modulations: a 4-kHz tone amplitude-modulated at 32 Hz plus a 6-kHz tone modulated at
200 Hz (both 100 %). Each carrier's channel shows energy in the band of its modulation.

Key numbers: for each carrier's channel and filterbank, the centre frequency of the
band with the most energy (the log filterbank's low-pass band aside) and, as truth, of
the band nearest the modulation frequency (on a log axis for ``'log'``, a linear one for
``'lin'``).

usage: python demo_ams.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import cf_edges, erb_axis, run, save_figure

FS = 16000.0
DURATION_S = 1.0
CARRIERS = ((4000.0, 32.0), (6000.0, 200.0))  # (carrier Hz, modulation Hz)
PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 23,
          "ams_wSizeSec": 0.032, "ams_hSizeSec": 0.016}


def modulated_tones() -> np.ndarray:
    """The sum of the CARRIERS tones, each 100 % amplitude-modulated."""
    t = np.arange(int(DURATION_S * FS)) / FS
    return sum(0.05 * (1 + np.sin(2 * np.pi * fm * t)) * np.sin(2 * np.pi * fc * t)
               for fc, fm in CARRIERS)


def band_edges(centres: np.ndarray, log: bool) -> np.ndarray:
    """Edges around modulation centre frequencies: geometric (``log``) or arithmetic midpoints."""
    c = np.log(centres) if log else centres
    mid = 0.5 * (c[1:] + c[:-1])
    edges = np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])
    return np.exp(edges) if log else np.maximum(edges, 0.0)


def main(outdir: str) -> Dict[str, float]:
    """Computes both modulation spectrograms, saves ``demo_ams.png``, returns the peak bands."""
    x = modulated_tones()
    fig, axes = plt.subplots(3, 1, figsize=(9, 13), constrained_layout=True)
    numbers: Dict[str, float] = {}
    for row, kind in enumerate(("log", "lin")):
        m = afe.Manager(FS, channels=1)
        m.add_request("amsFeatures", dict(PARAMS, ams_fbType=kind))
        ams = m.process_signal(x)["amsFeatures_mono"]  # [frame, channel, modulation band]
        info = m.info()["amsFeatures_mono"]
        cf, mod_cf = np.array(info["cf_hz"]), np.array(info["mod_cf_hz"])
        pattern = ams[4:].mean(axis=0)  # past the first frames' transient
        first = 1 if kind == "log" else 0  # the log filterbank's band 0 is a low-pass
        mesh = axes[row].pcolormesh(band_edges(mod_cf, kind == "log"), cf_edges(cf),
                                    10 * np.log10(pattern / pattern.max()), vmin=-30, vmax=0)
        fig.colorbar(mesh, ax=axes[row], label="mean AMS energy (dB re max)")
        erb_axis(axes[row])
        axes[row].set_ylim(2000, 8000)  # the carriers' region
        if kind == "log":
            axes[row].set_xscale("log")
        axes[row].set(xlabel="modulation centre frequency (Hz)",
                      title=f"Time-averaged AMS pattern, '{kind}' modulation filterbank")
        for fc, fm in CARRIERS:
            c = int(np.argmin(np.abs(cf - fc)))
            spectrum = pattern[c]
            numbers[f"{kind}_band_{fm:.0f}hz"] = float(mod_cf[first + np.argmax(spectrum[first:])])
            distance = np.abs(np.log(mod_cf / fm)) if kind == "log" else np.abs(mod_cf - fm)
            numbers[f"{kind}_nearest_{fm:.0f}hz"] = float(mod_cf[first + np.argmin(distance[first:])])
            axes[2].plot(mod_cf, 10 * np.log10(spectrum / spectrum.max()), "o-" if kind == "log" else "s--",
                         label=f"'{kind}', {fc / 1000:g}-kHz channel (modulated at {fm:g} Hz)")
    for _fc, fm in CARRIERS:
        axes[2].axvline(fm, color="gray", linestyle=":")
    axes[2].set_xscale("log")
    axes[2].set(xlabel="modulation centre frequency (Hz)", ylabel="energy re max (dB)",
                ylim=(-30, 1), title="Modulation spectra of the carriers' channels (dotted: true modulation)")
    axes[2].legend(fontsize=8)
    save_figure(fig, outdir, "demo_ams")
    return numbers


if __name__ == "__main__":
    run(main)
