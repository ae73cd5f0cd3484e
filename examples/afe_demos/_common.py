"""Helpers shared by the afe demos: the example signal and its known cues, time and
frequency axes, time-frequency images, and the command-line entry point.

Frames are drawn on the AFE's time axis: frame ``j`` of an output with frame rate
``fs_hz`` is at ``j / fs_hz`` seconds, the start of its analysis window (the times
``Manager.frames()`` reports). Frequency axes use the ERB-number scale of the auditory
filterbank, labelled in Hz.
"""

from __future__ import annotations

import os
import sys
from typing import Callable, Dict, Optional, Sequence, Tuple

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.collections import QuadMesh  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator  # noqa: E402

import afe  # noqa: E402

REPO_ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
EXAMPLE_WAV = os.path.join(REPO_ROOT, "data", "example_binaural.wav")

# Known content of data/example_binaural.wav (synthesised by tools/make_example_wav.py):
# a voiced, speech-like source on the listener's left.
EXAMPLE_ILD_DB = -6.0  # right re left, dB
EXAMPLE_ITD_S = -0.5e-3  # the right ear lags by 0.5 ms (AFE sign: positive = right leads)
EXAMPLE_VOICED_S = (0.1, 0.95)  # the voice is fully on in this interval, s
EXAMPLE_FORMANTS_HZ = (500.0, 1500.0, 2500.0)  # spectral-envelope resonances, Hz

FREQ_TICKS_HZ = (50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000)
DEFAULT_OUTDIR = "demo_figures"


def example_f0_hz(t_s: np.ndarray) -> np.ndarray:
    """Fundamental frequency of the example's voice (Hz) at time ``t_s`` (s): 110 → 180 Hz."""
    return 110.0 + 70.0 * np.asarray(t_s)


def read_example() -> Tuple[np.ndarray, float]:
    """The binaural example signal ``[samples, 2]`` (left, right) and its rate in Hz."""
    return afe.read_wav(EXAMPLE_WAV)


def frame_times(n_frames: int, fs_hz: float) -> np.ndarray:
    """AFE time of each frame (s): the start of its analysis window."""
    return np.arange(n_frames) / fs_hz


def sample_times(n_samples: int, fs_hz: float) -> np.ndarray:
    """Time of each sample of a time-domain signal (s)."""
    return np.arange(n_samples) / fs_hz


def hz_to_erb(f_hz: np.ndarray) -> np.ndarray:
    """ERB-number (Glasberg & Moore 1990) of frequencies in Hz: the filterbank's spacing."""
    return 9.265 * np.log1p(np.maximum(np.asarray(f_hz, dtype=float), 0.0) / (24.7 * 9.265))


def erb_to_hz(erb: np.ndarray) -> np.ndarray:
    """Inverse of :func:`hz_to_erb`."""
    return 24.7 * 9.265 * np.expm1(np.asarray(erb, dtype=float) / 9.265)


def erb_hz(f_hz: np.ndarray) -> np.ndarray:
    """Equivalent rectangular bandwidth of the auditory filter at ``f_hz`` (Hz)."""
    return 24.7 + 0.108 * np.asarray(f_hz, dtype=float)


def db_power(x: np.ndarray, floor: float = 1e-12) -> np.ndarray:
    """10·log10 of a power-like quantity (ratemap, energy), floored to avoid -inf."""
    return 10.0 * np.log10(np.maximum(x, floor))


def erb_axis(ax: Axes, axis: str = "y", label: str = "centre frequency (Hz)") -> None:
    """Puts ``axis`` ("x" or "y") of ``ax`` on the ERB-number scale, ticked in Hz."""
    scaler = ax.set_yscale if axis == "y" else ax.set_xscale
    scaler("function", functions=(hz_to_erb, erb_to_hz))
    target = ax.yaxis if axis == "y" else ax.xaxis
    target.set_major_locator(FixedLocator(FREQ_TICKS_HZ))
    target.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    target.set_minor_locator(NullLocator())
    target.set_label_text(label)


def cf_edges(cf_hz: Sequence[float]) -> np.ndarray:
    """Band edges (Hz) around centre frequencies: midpoints on the ERB-number scale."""
    e = hz_to_erb(np.asarray(cf_hz, dtype=float))
    if len(e) == 1:
        return erb_to_hz(np.array([e[0] - 0.5, e[0] + 0.5]))
    mid = 0.5 * (e[1:] + e[:-1])
    return erb_to_hz(np.concatenate([[2 * e[0] - mid[0]], mid, [2 * e[-1] - mid[-1]]]))


def tf_image(
    fig: Figure,
    ax: Axes,
    data: np.ndarray,
    fs_hz: float,
    cf_hz: Sequence[float],
    colorbar_label: str,
    cmap: str = "viridis",
    vmin: Optional[float] = None,
    vmax: Optional[float] = None,
) -> QuadMesh:
    """Draws a ``[frame or sample, channel]`` array as time (s) × centre frequency (Hz)."""
    t_edges = np.arange(data.shape[0] + 1) / fs_hz
    mesh = ax.pcolormesh(t_edges, cf_edges(cf_hz), data.T, cmap=cmap, vmin=vmin, vmax=vmax)
    erb_axis(ax)
    ax.set_xlabel("time (s)")
    fig.colorbar(mesh, ax=ax, label=colorbar_label)
    return mesh


def symmetric_limit(data: np.ndarray) -> float:
    """Largest finite magnitude of ``data``: colour limits ±it for signed maps (ILD, ITD)."""
    finite = np.abs(data[np.isfinite(data)])
    return float(finite.max()) if finite.size and finite.max() > 0 else 1.0


def waveplot(
    ax: Axes,
    data: np.ndarray,
    fs_hz: float,
    cf_hz: Sequence[float],
    t0_s: float = 0.0,
    zoom: float = 1.0,
) -> None:
    """Stacked traces of a ``[sample, channel]`` signal starting at ``t0_s`` seconds, one
    per channel, labelled by centre frequency (the AFE's ``waveplot``); the largest peak
    spans ``zoom`` times 0.9 of the spacing between traces."""
    peak = np.max(np.abs(data))
    scale = zoom * 0.9 / peak if peak > 0 else 1.0
    t = t0_s + sample_times(data.shape[0], fs_hz)
    for c in range(data.shape[1]):
        ax.plot(t, c + scale * data[:, c], color="k", linewidth=0.5)
    step = max(1, data.shape[1] // 8)
    ticks = np.arange(0, data.shape[1], step)
    ax.set_yticks(ticks)
    ax.set_yticklabels([f"{cf_hz[c]:.0f}" for c in ticks])
    ax.set_ylim(-1, data.shape[1])
    ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("centre frequency (Hz)")


def save_figure(fig: Figure, outdir: str, name: str) -> str:
    """Saves ``fig`` as ``<outdir>/<name>.png`` (creating ``outdir``), closes it, returns the path."""
    os.makedirs(outdir, exist_ok=True)
    path = os.path.join(outdir, f"{name}.png")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def run(main: Callable[[str], Dict[str, object]]) -> None:
    """Command-line entry point: ``python demo_x.py [outdir]``; prints the key numbers."""
    outdir = sys.argv[1] if len(sys.argv) > 1 else DEFAULT_OUTDIR
    numbers = main(outdir)
    for name, value in numbers.items():
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        print(f"{name}: {shown}")
