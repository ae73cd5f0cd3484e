"""Figures of afe's outputs with matplotlib (``pip install afe[plot]``).

One panel per signal, drawn as the plan its description gives (:attr:`afe.Signal.plan`,
computed in Rust, the same plan the ``afe plot`` command and the live page follow):
images over time and the rows of a frame (signed cues on a diverging map centred on
zero, powers and magnitudes in dB, masks in grey, features as z-scores), waveforms, the
frame of a two-axis signal (correlation, modulation spectrum, DUET histogram) at a
chosen time, and trajectories as lines. Axes are labelled from the signal's own axes,
colour bars with its unit.

Signals at the input's sampling rate (the ear signals, filterbank, inner-hair-cell and
adaptation outputs: whatever ``fs_hz`` equals ``audio_fs_hz`` for) are drawn as the AFE's
``waveplot`` draws them, one trace per channel stacked over the centre frequencies, or
optionally as images. Either way they are first reduced by :func:`envelope` to the
figure's pixel columns, keeping the smallest and the largest value of each column, so
that no peak is lost and a panel of 10 s at 44.1 kHz draws in a tenth of a second.
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .signal import Signal

#: The AFE's ``wavPlotZoom`` default: the largest magnitude of a stacked waveform lies
#: half this many channel spacings from its channel's line.
WAV_PLOT_ZOOM = 5.0


def new_figure(width: float, panels: int) -> Any:
    """A matplotlib ``Figure`` (no GUI backend) ``width`` inches wide for ``panels`` panels."""
    try:
        from matplotlib.figure import Figure
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("afe.plot needs matplotlib: pip install 'afe[plot]' (or matplotlib)") from e
    return Figure(figsize=(width, 2.4 * panels + 0.4), layout="constrained")


def _row_axis(ax: Any, axis: Optional[Mapping[str, Any]]) -> None:
    """Rows bottom to top by index, ticks labelled from the plan's axis (every row up to
    12, five of them beyond), titled with its label."""
    if not axis:
        return
    labels = axis["ticks"]
    n = len(labels)
    ticks = list(range(n)) if n <= 12 else sorted({0, n // 4, n // 2, (3 * n) // 4, n - 1})
    ax.set_yticks(ticks)
    ax.set_yticklabels([labels[k] for k in ticks], fontsize=7)
    ax.set_ylabel(axis["label"])


def envelope(values: np.ndarray, columns: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of ``values`` (``[time]`` or ``[time, channel]``) reduced to at most ``columns``
    columns: ``(starts, lo, hi)``, the first row of each column and the smallest and the
    largest value of each channel over the column's rows (NaN ignored unless a column
    holds nothing else). With no more rows than columns each row is its own column."""
    n = len(values)
    if n <= columns:
        return np.arange(n), values, values
    starts = np.arange(columns) * n // columns
    return starts, np.fmin.reduceat(values, starts, axis=0), np.fmax.reduceat(values, starts, axis=0)


def _pixel_columns(ax: Any) -> int:
    """The figure's width in pixels: at least as many columns as the axes can show."""
    return max(1, int(np.ceil(ax.figure.bbox.width)))


def _zigzag(t: np.ndarray, starts: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Points that run down and up each column, from its smallest value to its largest:
    a line through them covers every column's envelope. ``(x, y)``, y per channel."""
    if lo is hi:
        return t, lo
    x = np.repeat(t[starts], 2)
    y = np.empty((2 * len(starts),) + lo.shape[1:], dtype=np.result_type(lo, float))
    y[0::2], y[1::2] = lo, hi
    return x, y


def _waveforms(fig: Any, ax: Any, s: Signal, values: np.ndarray, t: np.ndarray, waveforms: bool,
               zoom: float) -> None:
    """An audio-rate signal reduced to the pixel columns: a trace (one per channel,
    stacked) or, without ``waveforms``, an image of the largest magnitude per column."""
    plan = s.plan
    starts, lo, hi = envelope(values, _pixel_columns(ax))
    if len(values) == 0:
        _row_axis(ax, plan["rows"])
        return
    if values.ndim == 1:
        ax.plot(*_zigzag(t, starts, lo, hi), lw=0.5, color="k")
        ax.set_ylabel(f"amplitude ({s.unit})" if s.unit else "amplitude")
        return
    if waveforms:
        # as the AFE's waveplot: each channel to zero mean and unit variance, then one
        # scale for all, the largest magnitude reaching zoom/2 channel spacings
        mean, std = values.mean(axis=0), values.std(axis=0)
        std = np.where(np.isfinite(std) & (std > 0), std, 1.0)
        lo, hi = (lo - mean) / std, (hi - mean) / std
        peak = float(np.nanmax(np.abs([lo, hi]))) if np.isfinite(lo).any() else 0.0
        scale = 0.5 * zoom / peak if peak > 0 else 0.0
        x, y = _zigzag(t, starts, lo, hi)
        from matplotlib.collections import LineCollection

        channels = np.arange(values.shape[1])
        segments = np.stack([np.broadcast_to(x[:, None], y.shape), channels + scale * y], axis=-1)
        # one [time, 2] line per channel, as the list LineCollection is typed to take
        lines = list(segments.transpose(1, 0, 2))
        ax.add_collection(LineCollection(lines, colors="k", linewidths=0.5))
        ax.set_ylim(-0.5 - 0.5 * zoom, values.shape[1] - 0.5 + 0.5 * zoom)
        _row_axis(ax, plan["rows"])
    else:
        largest = np.fmax(np.abs(lo), np.abs(hi))
        _over_time(fig, ax, plan, largest, [float(t[0]), float(t[-1] + 1.0 / s.fs_hz)], peaks=True)


def _over_time(fig: Any, ax: Any, plan: Mapping[str, Any], values: np.ndarray, span: Sequence[float],
               peaks: bool = False) -> None:
    """``values`` (``[time, row]``) as an image over ``span`` (s) on the plan's scale;
    ``peaks``: each column holds the largest magnitude of the samples it stands for."""
    scale = plan["scale"]
    extent = [span[0], span[1], -0.5, values.shape[1] - 0.5]
    label = plan["values"] or "value"
    cmap = "magma" if plan["complex"] else None
    if plan["complex"]:
        values = np.abs(values)
    kind = scale["scale"]
    if kind in ("power-decibels", "amplitude-decibels"):
        db = 10 * np.log10(np.maximum(values, 1e-30)) if kind == "power-decibels" \
            else 20 * np.log10(np.maximum(np.abs(values), 1e-300))
        peak = float(np.max(db))
        unit = "dB (largest |value|)" if peaks and kind == "amplitude-decibels" else "dB"
        _image(fig, ax, db.T, extent, unit, vmin=peak - scale["range_db"], vmax=peak, cmap=cmap)
    elif kind == "mask":
        _image(fig, ax, values.T, extent, label, vmin=0, vmax=1, cmap="gray_r")
    elif kind == "z-scores":
        # each row on its own scale: z-scores over time
        mean = np.nanmean(values, axis=0)
        std = np.nanstd(values, axis=0)
        z = (values - mean) / np.where(std > 0, std, 1.0)
        _image(fig, ax, z.T, extent, label, signed=True)
    else:
        unit = f"largest |value| ({plan['values']})" if peaks and plan["values"] else \
            "largest |value|" if peaks else label
        _image(fig, ax, values.T, extent, unit, signed=kind == "signed")
    _row_axis(ax, plan["rows"])


def _image(fig: Any, ax: Any, data: np.ndarray, extent: Sequence[float], unit: str,
           signed: bool = False, vmin: Optional[float] = None, vmax: Optional[float] = None,
           cmap: Optional[str] = None) -> None:
    finite = data[np.isfinite(data)]
    if signed:
        lim = float(np.max(np.abs(finite))) if finite.size else 1.0
        vmin, vmax, cmap = -lim or -1.0, lim or 1.0, cmap or "RdBu_r"
    im = ax.imshow(data, origin="lower", aspect="auto", extent=extent, interpolation="nearest",
                   cmap=cmap or "viridis", vmin=vmin, vmax=vmax)
    bar = fig.colorbar(im, ax=ax, pad=0.01)
    bar.set_label(unit)


def _row_at(s: Signal, at: Optional[float]) -> Tuple[int, float]:
    """The row drawn for a layout shown one frame at a time: the one at time ``at`` (s),
    by default the middle one."""
    t = s.t_s
    if len(t) == 0:
        raise ValueError(f"{s.key} is empty: nothing to draw")
    if at is None:
        k = len(t) // 2
    else:
        if not t[0] <= at <= t[-1] + 1.0 / s.fs_hz:
            raise ValueError(f"at = {at} s is outside {s.key}, which covers {t[0]:g} to {t[-1]:g} s")
        k = int(np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1))
    return k, float(t[k])


def draw(fig: Any, ax: Any, s: Signal, at: Optional[float] = None, waveforms: bool = True,
         wavPlotZoom: float = WAV_PLOT_ZOOM) -> None:
    """Draws signal ``s`` on the axes ``ax`` of figure ``fig`` as its plan says (see
    :func:`plot` and :attr:`afe.Signal.plan`)."""
    values = np.asarray(s)
    t = s.t_s
    plan = s.plan
    panel = plan["panel"]
    span = [float(t[0]) if len(t) else 0.0, float(t[-1] + 1.0 / s.fs_hz) if len(t) else 1.0]
    title = s.key
    if panel == "waveforms":
        _waveforms(fig, ax, s, values, t, waveforms, wavPlotZoom)
    elif panel == "over-time":
        _over_time(fig, ax, plan, values.reshape(len(values), -1), span)
    elif panel == "line":
        ax.plot(t, values.reshape(len(values), -1)[:, 0], ".", ms=2)
        ax.set_ylabel(plan["values"] or s.key)
    elif panel == "from-above":
        # over a whole signal: each tracked source's azimuth over time, and the head's yaw
        scene = plan["from_above"]
        rows = values.reshape(len(values), -1)
        for k in range(scene["slots"]):
            az = rows[:, k * scene["slot_width"] + scene["azimuth"]]
            ax.plot(t, az, ".", ms=2, color=f"C{k}")
        ax.plot(t, rows[:, scene["head_yaw"]] % 360.0, "-", lw=1, color="0.5", label="head yaw")
        ax.set_ylim(0.0, 360.0)
        ax.set_ylabel(plan["values"])
        ax.legend(loc="upper right", fontsize=8)
    elif panel == "frame":
        k, when = _row_at(s, at)
        frame = values[k].reshape(len(plan["rows"]["values"]), -1)
        across = plan["across"]["values"]
        _image(fig, ax, frame, [across[0], across[-1], -0.5, frame.shape[0] - 0.5], plan["values"] or "value",
               signed=bool(np.nanmin(frame) < 0))
        ax.set_xlabel(plan["across"]["label"])
        _row_axis(ax, plan["rows"])
        title = f"{s.key} at {when:.3f} s"
    else:
        raise ValueError(f"{s.key}: no drawing for a {panel!r} panel")
    if panel != "frame":
        ax.set_xlim(span)
        ax.set_xlabel("time (s)")
    ax.set_title(title, fontsize=10, loc="left")


def plot(
    source: Union[Mapping[str, Signal], np.ndarray, str, "os.PathLike[str]"],
    requests: Optional[Union[str, Sequence[str]]] = None,
    params: Optional[Mapping[str, Any]] = None,
    fs: Optional[float] = None,
    out: Optional[Union[str, "os.PathLike[str]"]] = None,
    at: Optional[float] = None,
    width: float = 10.0,
    waveforms: bool = True,
    wavPlotZoom: float = WAV_PLOT_ZOOM,
) -> Any:
    """Draws representations, one panel per signal; returns the matplotlib ``Figure``.

    ``source``: the dict of :class:`afe.Signal` that :func:`afe.process` returns, or a
    WAV path or an array (with ``fs``) to compute ``requests`` with ``params`` on.
    ``out``: save the figure there (PNG, SVG, PDF by its extension). ``at``: the time in
    s of the frame drawn for correlations, modulation features and DUET histograms
    (default: the middle). ``width``: figure width in inches.

    Signals at the input's sampling rate (``fs_hz == audio_fs_hz``: the ear signals,
    filterbank, inner-hair-cell and adaptation outputs) are drawn as waveforms, one trace
    per channel stacked over the centre frequencies, each channel brought to zero mean
    and unit variance and all on one scale, as the AFE's ``waveplot``: the largest magnitude
    lies ``wavPlotZoom / 2`` channel spacings from its channel's line (the AFE's 5).
    ``waveforms=False`` draws them as images instead, of the largest magnitude per pixel
    column, in dB where the signal's ``display`` gives a range. Both keep each pixel
    column's smallest and largest value (:func:`envelope`), so no peak is lost.
    """
    from . import process

    if isinstance(source, Mapping):
        signals = dict(source)
    else:
        if requests is None:
            raise ValueError("give the requests to compute (afe.requests() lists them)")
        signals = process(source, fs, requests, params)
    for key, s in signals.items():
        if not isinstance(s, Signal):
            raise ValueError(f"'{key}' is a plain array: pass afe.process's output (afe.Signal objects)")
    if not signals:
        raise ValueError("nothing to draw")
    fig = new_figure(width, len(signals))
    axes = fig.subplots(len(signals), 1, squeeze=False)[:, 0]
    for ax, s in zip(axes, signals.values()):
        draw(fig, ax, s, at, waveforms, wavPlotZoom)
    if out is not None:
        fig.savefig(os.fspath(out), dpi=100)
    return fig
