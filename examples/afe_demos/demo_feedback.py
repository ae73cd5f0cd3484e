"""Feedback: changing a parameter while streaming (``Manager.modify_parameter``).

Ports the AFE's ``DEMO_Feedback``: a 1-kHz tone is streamed chunk by chunk into a
ratemap request, and before each chunk the gammatone bandwidth ``fb_bwERBs`` is raised,
from 1 to 4 ERB. The filterbank (and everything computed from it) is rebuilt at each
change, so the tone's excitation pattern across channels widens from chunk to chunk.
``Manager.frames()`` tells where each chunk's frames stand in the stream: their times
keep increasing across the changes (each rebuild restarts the framing at the chunk's
first sample, so a chunk has one frame fewer than a continuous stream would).

Key numbers: whether the frame times are strictly increasing; the −10 dB width of the
excitation pattern in the first and last chunk, and the widths predicted for a 4th-order
gammatone, |H|² = (1 + u²)^−4 with u = (f − cf)/(fb_bwERBs · ERB(cf)).

usage: python demo_feedback.py [outdir]
"""

from __future__ import annotations

from typing import Dict, List

import matplotlib.pyplot as plt
import numpy as np

import afe
from _common import cf_edges, erb_axis, erb_to_hz, hz_to_erb, run, save_figure

FS = 16000.0
TONE_HZ = 1000.0
DURATION_S = 2.0
CHUNK = 1600  # samples (0.1 s)
BANDWIDTHS_ERB = (1.0, 4.0)  # fb_bwERBs of the first and the last chunk
PARAMS = {"fb_nChannels": 64}
DROP_DB = 10.0  # level below the peak at which the pattern's width is measured


def pattern_width_hz(level_db: np.ndarray, cf: np.ndarray) -> float:
    """Width (Hz) of the region where a one-peaked excitation pattern is within ``DROP_DB``
    of its maximum, interpolating linearly on the ERB-number scale."""
    e = hz_to_erb(cf)
    rel = level_db - level_db.max() + DROP_DB  # > 0 inside the region
    top = int(np.argmax(level_db))
    lo = next(c for c in range(top, 0, -1) if rel[c - 1] <= 0)
    hi = next(c for c in range(top, len(cf) - 1) if rel[c + 1] <= 0)
    e_lo = e[lo - 1] + (e[lo] - e[lo - 1]) * rel[lo - 1] / (rel[lo - 1] - rel[lo])
    e_hi = e[hi] + (e[hi + 1] - e[hi]) * rel[hi] / (rel[hi] - rel[hi + 1])
    return float(erb_to_hz(e_hi) - erb_to_hz(e_lo))


def predicted_width_hz(bw_erb: float) -> float:
    """Width (Hz) of the centre-frequency range where a 4th-order gammatone passes a pure
    tone at most DROP_DB down: |H|² = (1 + u²)^−4 ≥ 10^(−DROP_DB/10) for
    |f − cf| ≤ u · bw_erb · (24.7 + 0.108 · cf), u = sqrt(10^(DROP_DB/40) − 1)."""
    u = np.sqrt(10 ** (DROP_DB / 40) - 1)
    k = u * bw_erb
    return float((TONE_HZ + 24.7 * k) / (1 - 0.108 * k) - (TONE_HZ - 24.7 * k) / (1 + 0.108 * k))


def main(outdir: str) -> Dict[str, object]:
    """Streams the tone while widening the filters, saves ``demo_feedback.png``, returns the checks."""
    t = np.arange(int(DURATION_S * FS)) / FS
    tone = 0.5 * np.sin(2 * np.pi * TONE_HZ * t)
    n_chunks = len(tone) // CHUNK
    bandwidths = np.linspace(*BANDWIDTHS_ERB, n_chunks)

    m = afe.Manager(FS, channels=1)
    m.add_request("ratemap", PARAMS)
    frames: List[np.ndarray] = []
    times: List[np.ndarray] = []
    for i, bw in enumerate(bandwidths):
        m.modify_parameter("fb_bwERBs", float(bw))
        new = m.process_chunk(tone[i * CHUNK:(i + 1) * CHUNK])["ratemap_mono"]
        where = m.frames()["ratemap_mono"]
        frames.append(new)
        times.append(where["first_time_s"] + np.arange(new.shape[0]) / where["fs_hz"])
    info = m.info()["ratemap_mono"]
    cf = np.array(info["cf_hz"])
    frame_t = np.concatenate(times)
    top_db = 10 * np.log10(max(f.max() for f in frames))
    patterns = {i: 10 * np.log10(frames[i][-1]) for i in (0, n_chunks - 1)}  # last frame of a chunk
    widths = {i: pattern_width_hz(p, cf) for i, p in patterns.items()}

    fig, axes = plt.subplots(2, 1, figsize=(9, 9), constrained_layout=True)
    for t_chunk, block in zip(times, frames):  # one image per chunk: the framing restarts
        t_edges = np.append(t_chunk, t_chunk[-1] + 1 / info["fs_hz"])
        mesh = axes[0].pcolormesh(t_edges, cf_edges(cf), 10 * np.log10(block).T,
                                  vmin=top_db - 60, vmax=top_db)
    fig.colorbar(mesh, ax=axes[0], label="level (dB re 1)")
    erb_axis(axes[0])
    axes[0].set(xlabel="time (s; from Manager.frames())", ylim=(300, 4000),
                title="Ratemap of a 1-kHz tone while fb_bwERBs grows (value at each chunk's start)")
    for i in range(0, n_chunks, 4):
        axes[0].text(times[i][0] + 0.01, 3300, f"{bandwidths[i]:.2g}", color="w", fontsize=9)
    for (i, pattern), style in zip(patterns.items(), ("C0", "C3")):
        axes[1].plot(cf, pattern - pattern.max(), style + "o-", markersize=3,
                     label=f"fb_bwERBs = {bandwidths[i]:g}: width {widths[i]:.0f} Hz "
                           f"(predicted {predicted_width_hz(bandwidths[i]):.0f} Hz)")
    axes[1].axhline(-DROP_DB, color="gray", linestyle="--", linewidth=0.8)
    erb_axis(axes[1], "x")
    axes[1].set(ylabel="level re peak (dB)", ylim=(-60, 3), xlim=(200, 5000),
                title="Excitation pattern in the first and the last chunk (dashed: −10 dB)")
    axes[1].legend(loc="upper left")
    save_figure(fig, outdir, "demo_feedback")
    last = n_chunks - 1
    return {
        "frame_times_increasing": bool(np.all(np.diff(frame_t) > 0)),
        "frames_per_chunk": int(frames[0].shape[0]),
        "width_first_hz": widths[0],
        "width_first_predicted_hz": predicted_width_hz(bandwidths[0]),
        "width_last_hz": widths[last],
        "width_last_predicted_hz": predicted_width_hz(bandwidths[last]),
    }


if __name__ == "__main__":
    run(main)
