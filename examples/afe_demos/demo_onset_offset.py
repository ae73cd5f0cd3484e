"""Onset and offset strengths and the onset/offset maps derived from them.

Ports the AFE's ``DEMO_OnsetStrength``, ``DEMO_OffsetStrength`` and
``DEMO_OnsetOffsetMaps``: the onset (offset) strength is the frame-to-frame rise (fall)
of the ratemap level in dB; the maps keep the salient transients (peaks over time,
fused within 30 ms, at least 5 connected cells, ratemap level above −80 dB). The input
has known events: a 1-kHz tone from 0.2 to 0.6 s and a 4-kHz tone from 0.4 to 0.8 s
(5-ms raised-cosine ramps) over noise about 80 dB lower.

Key numbers: the time of each tone's onset and offset in the maps (the middle of the
first frame marked near the tone's channel; truth: the events above; onsets are marked
within a frame, offsets up to 30 ms late, as the ratemap's window and leaky integrator
smear the fall), and the offset strength in the 4-kHz channel in the 40 ms after that
tone stops. There the ratemap decays at the rate of its leaky integrator (time constant
``rm_decaySec`` = 8 ms on the envelope, twice as fast on the power), i.e. by
20·log10(e)·10 ms / 8 ms = 10.86 dB per 10-ms frame.

usage: python demo_onset_offset.py [outdir]
"""

from __future__ import annotations

from typing import Dict

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap

import afe
from _common import cf_edges, db_power, frame_times, run, save_figure, tf_image

FS = 16000.0
TONES = ((1000.0, 0.2, 0.6), (4000.0, 0.4, 0.8))  # (frequency Hz, on s, off s)
RAMP_S = 0.005
PARAMS = {"fb_lowFreqHz": 80, "fb_highFreqHz": 8000, "fb_nChannels": 64, "ihc_method": "dau",
          "rm_wSizeSec": 0.02, "rm_hSizeSec": 0.01, "rm_decaySec": 0.008, "rm_wname": "hann",
          "trm_minValuedB": -80, "trm_minStrengthdB": 3, "trm_minSpread": 5,
          "trm_fuseWithinSec": 0.03}
NEAR_CHANNELS = 2  # a map cell belongs to a tone if its channel is this close to the tone's


def tone_bursts(fs: float, duration_s: float = 1.0) -> np.ndarray:
    """The two gated tones of TONES plus noise about 80 dB below them."""
    t = np.arange(int(duration_s * fs)) / fs
    x = 1e-5 * np.random.default_rng(5).standard_normal(t.size)
    for f, on, off in TONES:
        gate = np.sin(0.5 * np.pi * np.clip(np.minimum(t - on, off - t) / RAMP_S, 0, 1)) ** 2
        x += 0.1 * gate * np.sin(2 * np.pi * f * t)
    return x


def main(outdir: str) -> Dict[str, float]:
    """Computes strengths and maps, saves ``demo_onset_offset.png``, returns the event times."""
    m = afe.Manager(FS, channels=1)
    for request in ("ratemap", "onsetStrength", "offsetStrength", "onsetMap", "offsetMap"):
        m.add_request(request, PARAMS)
    out = m.process_signal(tone_bursts(FS))
    info = m.info()["onsetMap_mono"]
    cf = np.array(info["cf_hz"])
    t = frame_times(out["onsetMap_mono"].shape[0], info["fs_hz"])
    centre = t + PARAMS["rm_wSizeSec"] / 2  # middle of each frame's window

    numbers: Dict[str, float] = {}
    for f, _on, _off in TONES:
        near = np.abs(np.arange(len(cf)) - np.argmin(np.abs(cf - f))) <= NEAR_CHANNELS
        for kind in ("onset", "offset"):
            marked = out[f"{kind}Map_mono"][:, near].any(axis=1)
            numbers[f"{kind}_{int(f)}hz_s"] = float(centre[np.argmax(marked)])
    channel_4k = np.argmin(np.abs(cf - TONES[1][0]))
    silence = (t >= TONES[1][2] + 0.01) & (t < TONES[1][2] + 0.05)  # before the noise floor
    numbers["offset_strength_in_silence_db"] = float(
        np.median(out["offsetStrength_mono"][silence, channel_4k]))
    numbers["decay_rate_db_per_frame"] = float(
        20 * np.log10(np.e) * PARAMS["rm_hSizeSec"] / PARAMS["rm_decaySec"])

    fig, axes = plt.subplots(3, 1, figsize=(9, 11), sharex=True, constrained_layout=True)
    level = db_power(out["ratemap_mono"])
    tf_image(fig, axes[0], out["onsetStrength_mono"], info["fs_hz"], cf, "onset strength (dB)",
             cmap="Reds")
    axes[0].set_title("Onset strength (rise of the ratemap level)")
    tf_image(fig, axes[1], out["offsetStrength_mono"], info["fs_hz"], cf, "offset strength (dB)",
             cmap="Blues")
    axes[1].set_title("Offset strength (fall of the ratemap level)")
    tf_image(fig, axes[2], level, info["fs_hz"], cf, "ratemap level (dB re 1)", cmap="gray",
             vmin=level.max() - 90, vmax=level.max())
    t_edges = np.append(t, t[-1] + 1 / info["fs_hz"])
    for kind, colour in (("onset", "red"), ("offset", "deepskyblue")):
        cells = np.ma.masked_equal(out[f"{kind}Map_mono"], 0)  # draw the marked cells only
        axes[2].pcolormesh(t_edges, cf_edges(cf), cells.T, cmap=ListedColormap([colour]))
    axes[2].set_title("Onset (red) and offset (blue) maps over the ratemap")
    for ax in axes:
        for _f, on, off in TONES:
            for event in (on, off):
                ax.axvline(event, color="k", linestyle=":", linewidth=0.8)
    save_figure(fig, outdir, "demo_onset_offset")
    return numbers


if __name__ == "__main__":
    run(main)
