"""Signal objects: afe's outputs as numpy arrays that carry their description.

A :class:`Signal` is an ``ndarray`` (float64, or complex128 for spectra) with the AFE
signal's description attached: name, ear, kind, rates, the time of each row, centre
frequencies, lags, feature names, window and hop, and the parameters of the processor
chain that computed it. numpy code keeps working on it unchanged. Arrays derived from it
(slices, arithmetic, reductions) are plain ``ndarray`` objects, since the description
would no longer fit them.
"""

from __future__ import annotations

from typing import Any, Dict, List, Mapping, Optional

import numpy as np


def _rebuild(data: np.ndarray, meta: Dict[str, Any]) -> "Signal":
    return Signal(data, meta)


class Signal(np.ndarray):
    """One output of afe: the values (``[time]``, ``[frame, channel]``, ...) and what they are.

    Rows are in time: row ``k`` is at ``t_s[k] = first_time_s + k / fs_hz`` seconds from
    the start of the stream. For framed signals that is the start of the frame's window
    (frame ``k`` covers input samples ``[k·H, k·H + W)``, the AFE's framing, whose time
    axis starts at 0 with the first frame).
    """

    _meta: Dict[str, Any]

    def __new__(cls, data: Any, meta: Mapping[str, Any]) -> "Signal":
        obj = np.asarray(data).view(cls)
        obj._meta = dict(meta)
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        self._meta = getattr(obj, "_meta", {})

    def __array_wrap__(self, array: np.ndarray, context: Any = None, return_scalar: bool = False) -> Any:
        # results of ufuncs and reductions are new values: plain arrays (or scalars)
        plain = np.asarray(array).view(np.ndarray)
        return plain[()] if return_scalar else plain

    def __getitem__(self, key: Any) -> Any:
        item = super().__getitem__(key)
        # a slice or a channel selection no longer matches the description
        return item.view(np.ndarray) if isinstance(item, np.ndarray) else item

    def __reduce__(self) -> Any:
        return (_rebuild, (np.asarray(self).view(np.ndarray).copy(), self._meta))

    def __repr__(self) -> str:
        m = self._meta
        what = f"{m.get('key', '?')}: {m.get('kind', '?')} {list(self.shape)} {list(m.get('axes', []))}"
        rate = f", {m['fs_hz']:g} Hz" if "fs_hz" in m else ""
        return f"afe.Signal({what}{rate})\n{np.asarray(self).view(np.ndarray)!r}"

    @property
    def meta(self) -> Dict[str, Any]:
        """The whole description, as a dict (a copy): every property below and more."""
        return dict(self._meta)

    @property
    def key(self) -> str:
        """Output name, ``<request>_<ear>`` (``ratemap_2_left`` for a second instance)."""
        return self._meta["key"]

    @property
    def name(self) -> str:
        """The AFE signal's name: the request's (``ratemap``), or the output's own
        (``precedence_itd``)."""
        return self._meta["name"]

    @property
    def ear(self) -> str:
        """``left``, ``right`` or ``mono`` (binaural cues and mono input)."""
        return self._meta["ear"]

    @property
    def unit(self) -> str:
        """Unit of the values (``dB``, ``s``, ``Hz``; empty where the AFE gives none)."""
        return self._meta["unit"]

    @property
    def kind(self) -> str:
        """``time-domain``, ``time-frequency``, ``correlation``, ``modulation``,
        ``feature``, ``spectrum``, ``binary-mask`` or ``duet-histogram``."""
        return self._meta["kind"]

    @property
    def afe_class(self) -> str:
        """The MATLAB AFE's signal class (``TimeFrequencySignal``, ...)."""
        return self._meta["afe_class"]

    @property
    def axes(self) -> List[str]:
        """Name of each array axis, e.g. ``["frame", "channel"]``."""
        return list(self._meta["axes"])

    @property
    def fs_hz(self) -> float:
        """Rows per second: the sampling rate, or the frame rate of framed signals."""
        return self._meta["fs_hz"]

    @property
    def audio_fs_hz(self) -> float:
        """Sampling rate in Hz of the audio the signal was computed from."""
        return self._meta["audio_fs_hz"]

    @property
    def first_frame(self) -> int:
        """Index of row 0 among all the rows this output has given in its stream."""
        return self._meta["first_frame"]

    @property
    def first_time_s(self) -> float:
        """Time of row 0 in seconds from the start of the stream."""
        return self._meta["first_time_s"]

    @property
    def t_s(self) -> np.ndarray:
        """Time of each row in seconds from the start of the stream."""
        return self.first_time_s + np.arange(self.shape[0]) / self.fs_hz

    @property
    def display(self) -> Dict[str, Any]:
        """How the values are best drawn: ``{"draw": "signed"}``, ``{"draw":
        "power-decibels", "range_db": 60.0}``, ``"amplitude-decibels"``, ``"linear"`` or
        ``"trajectory"`` (one value per frame as a line)."""
        return self._meta["display"]

    @property
    def frame_axes(self) -> List[Dict[str, Any]]:
        """The axes of a frame after time, outermost first: each a dict of ``name``,
        ``quantity``, ``unit`` and ``values`` (or ``labels``, for feature names)."""
        return list(self._meta["frame_axes"])

    @property
    def plan(self) -> Dict[str, Any]:
        """How the signal is drawn, computed in Rust from its description: ``panel``
        (``waveforms``, ``line``, ``over-time`` or ``frame``), ``scale`` (``{"scale":
        "power-decibels", "range_db": 60.0}``, ...), ``rows`` and ``across`` (each a
        ``label``, ``values`` and ``ticks``, or ``None``), the ``values`` label, ``peaks``
        and ``complex``. :func:`afe.plot.draw` follows it."""
        return self._meta["plan"]

    @property
    def window_s(self) -> Optional[float]:
        """Frame window length in s as set (``rm_wSizeSec``, ...); ``None`` unless framed."""
        return self._meta["window_s"]

    @property
    def hop_s(self) -> Optional[float]:
        """Time between frames in s (``1 / fs_hz``); ``None`` unless framed."""
        return self._meta["hop_s"]

    @property
    def nan_where(self) -> Optional[str]:
        """Where this representation holds NaN from finite input, as the AFE's does (an
        unvoiced pitch frame, an autocorrelation frame of silence, ...); ``None`` where
        it never does (docs/conformance.md)."""
        return self._meta.get("nan_where")

    @property
    def cf_hz(self) -> np.ndarray:
        """Centre frequency of each channel in Hz (bin frequencies of a spectrum). Feature
        signals have no channels: the filterbank's centre frequencies that spectral
        features are computed over are in ``parameters["fb_cfHz"]``."""
        return np.asarray(self._meta["cf_hz"], dtype=float)

    @property
    def n_channels(self) -> int:
        """Number of frequency channels (0 for time-domain and feature signals)."""
        return self._meta["n_channels"]

    @property
    def lags_s(self) -> np.ndarray:
        """Lag of each correlation column in s."""
        return np.asarray(self._meta["lags_s"], dtype=float)

    @property
    def mod_cf_hz(self) -> np.ndarray:
        """Modulation centre frequencies in Hz (AMS features)."""
        return np.asarray(self._meta["mod_cf_hz"], dtype=float)

    @property
    def features(self) -> List[str]:
        """Feature names in column order (spectral features, pitch, ...)."""
        return list(self._meta["features"])

    @property
    def delay_s(self) -> Optional[np.ndarray]:
        """Per-channel filterbank delay in s (the AFE's ``delaySec``: the envelope peak
        delay of each gammatone channel), ``None`` where no gammatone is in the chain."""
        d = self._meta["parameters"].get("fb_delaySec")
        return None if d is None else np.asarray(d, dtype=float)

    @property
    def parameters(self) -> Dict[str, Any]:
        """The effective parameters of every processor in the chain, defaults included
        (the AFE's ``getParameterSummary``)."""
        return dict(self._meta["parameters"])

    @property
    def processors(self) -> List[str]:
        """The chain of processors that computed the signal, nearest first."""
        return list(self._meta["processors"])

    def plot(self, ax: Any = None, at: Optional[float] = None, waveforms: bool = True,
             wavPlotZoom: float = 5.0, width: float = 10.0) -> Any:
        """Draws this signal as :func:`afe.plot` draws each panel; returns the matplotlib
        ``Figure``. ``ax``: the axes to draw on (their figure gets the colour bar); by
        default a new figure ``width`` inches wide. ``at``, ``waveforms`` and
        ``wavPlotZoom`` as for :func:`afe.plot`."""
        from .plot import draw, new_figure

        if ax is None:
            fig = new_figure(width, 1)
            ax = fig.subplots()
        draw(ax.figure, ax, self, at, waveforms, wavPlotZoom)
        return ax.figure


def signals(arrays: Mapping[str, np.ndarray], meta: Mapping[str, Mapping[str, Any]]) -> Dict[str, Signal]:
    """``{name: Signal}`` from ``{name: array}`` and ``{name: description}``."""
    return {k: Signal(v, meta[k]) for k, v in arrays.items()}
