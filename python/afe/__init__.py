"""afe: a real-time binaural Auditory Front-End, the Two!Ears AFE from Python.

Place requests by their AFE names (``ratemap``, ``ild``, ``itd``, ``ic``,
``crosscorrelation``, ``innerhaircell``, ``filterbank``, ``time``, ``butterworth``),
set parameters by their AFE names (``fb_nChannels``, ``ihc_method``, ``rm_wSizeSec``, ...),
and get numpy arrays named ``<request>_<left|right|mono>`` in the layouts of the MATLAB
AFE: ``[time]``, ``[frame, channel]`` or ``[frame, channel, lag]``, float64. Each is an
:class:`afe.Signal`, an ``ndarray`` that carries its description (rates, time of each
row, centre frequencies, lags, window and hop, the parameters it was computed with).

Streams come in blocks, each an :class:`afe.Frames` of every output's new frames:
:func:`afe.stream` computes them from a recording here; :func:`afe.connect` subscribes
to those ``afe serve`` computes from its live audio, over Zenoh.

>>> import afe, numpy as np
>>> fs = 16000
>>> t = np.arange(fs) / fs
>>> left = np.sin(2 * np.pi * 500 * t)
>>> out = afe.process(np.column_stack([left, 0.5 * left]), fs, ["ild"])
>>> out["ild_mono"].shape
(99, 31)
>>> out["ild_mono"].hop_s, out["ild_mono"].parameters["ild_wSizeSec"]
(0.01, 0.02)
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _afe
from .frames import Requests, request_items as _request_items
from .signal import Signal, signals as _signals

__all__ = [
    "Audio",
    "AudioBlock",
    "Frames",
    "Manager",
    "Remote",
    "RemoteError",
    "Signal",
    "Store",
    "Subscription",
    "batch",
    "connect",
    "heads",
    "host",
    "load",
    "locate",
    "open_store",
    "parameters",
    "plot",
    "process",
    "raa",
    "read_wav",
    "render",
    "requests",
    "save",
    "stream",
    "summary",
    "transfer",
    "__version__",
]


def __dir__() -> List[str]:
    """The public API only (not the modules and typing names imported here)."""
    return sorted(__all__)
__version__ = _afe.__version__

Audio = Union[np.ndarray, Sequence[float], Sequence[Sequence[float]], str, os.PathLike]


def _catalog() -> List[Dict[str, Any]]:
    return _afe.catalog()


def requests() -> List[str]:
    """The request names afe knows, in dependency order."""
    return [r["name"] for r in _catalog()]


def parameters(request: Optional[str] = None) -> List[Dict[str, Any]]:
    """The AFE parameters with their defaults, units and meanings (as ``afe list``).

    Without an argument: every parameter. With a request name: the parameters of every
    processor that request is computed through (e.g. ``ratemap`` → ratemap, IHC,
    filterbank and pre-processing parameters). With a parameter name (``fb_nChannels``):
    that parameter alone, as a one-entry list. Each entry is a dict with ``name``,
    ``processor``, ``type``, ``accepts``, ``default``, ``unit`` and ``description``.

    Raises ``ValueError`` for a name that is neither, naming close matches.
    """
    catalog = {r["name"]: r for r in _catalog()}
    every = [dict(p, processor=n) for n in catalog for p in catalog[n]["parameters"]]
    if request is None:
        return every
    if request in catalog:
        return [dict(p, processor=n) for n in catalog[request]["chain"] for p in catalog[n]["parameters"]]
    found = [p for p in every if p["name"] == request]
    if found:
        # a parameter shared by processors (the filterbank's) is listed once
        return found[:1]
    import difflib

    close = difflib.get_close_matches(request, list(catalog) + [p["name"] for p in every], n=3)
    hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
    raise ValueError(f"'{request}' is neither a request nor a parameter{hint}")


def host() -> Dict[str, Any]:
    """The machine a timing comes from, to keep beside it (as ``afe bench --json``).

    A dict with ``cpu`` (the model name), ``cores`` (logical cores this process may use),
    ``simd`` (the instruction set the kernels take: ``avx512``, ``avx2`` or
    ``baseline``), ``avx512_available`` (``simd == "avx2"`` with it is the forced AVX2
    path of a ``no-avx512`` build), ``version`` and ``core_to_core_ns`` (one cache
    line's round trip between two threads, measured now in a few ms: about 80 ns where
    the cores share a last-level cache, 350 ns and more where they do not, when
    ``threads=2`` gains less; ``None`` with one core, or on a machine too busy to run
    two threads side by side).
    """
    return _afe.host()


def read_wav(path: Union[str, os.PathLike]) -> Tuple[np.ndarray, float]:
    """Reads a WAV file (PCM 8/16/24/32-bit or float; full scale = 1.0).

    Returns ``(samples, fs)``: a float64 array, 1-D for a mono file and ``[samples, 2]``
    for a binaural one, and the sampling rate in Hz. Raises ``FileNotFoundError`` for a
    missing file and ``ValueError`` for a file that is not a readable WAV.
    """
    x, fs = _afe.read_wav(os.fspath(path))
    return (x[:, 0].copy() if x.shape[1] == 1 else x), fs


def _as_channels(signal: Audio, channels: Optional[int] = None) -> np.ndarray:
    """A C-contiguous float64 ``[samples, channels]`` array, with clear errors."""
    raw = np.asarray(signal)
    if np.issubdtype(raw.dtype, np.integer):
        # raw PCM counts would be taken as amplitudes 32768 times too large
        scale = 2.0 ** (8 * raw.dtype.itemsize - 1)
        raise ValueError(
            f"the signal holds integers ({raw.dtype}): afe takes float samples with full "
            f"scale 1.0, e.g. x / {scale:.0f} for {raw.dtype} PCM"
        )
    x = np.asarray(raw, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[1] not in (1, 2):
        hint = ""
        if x.ndim == 2 and x.shape[0] in (1, 2):
            # MATLAB's column-major files come out of h5py (v7.3) as [channels, samples]
            hint = f": it looks like [channels, samples]; pass x.T (shape {x.shape[::-1]})"
        raise ValueError(
            f"signal of shape {x.shape}: expected [samples] (mono) or [samples, 2] (left, right){hint}"
        )
    if channels is not None and x.shape[1] != channels:
        n = x.shape[0]
        if channels == 2:
            expected = "[samples, 2] (left, right)"
            hint = f"give np.column_stack([left, right]) (shape ({n}, 2))"
        else:
            expected = "[samples]"
            hint = f"pass one ear, x[:, 0] (shape ({n},)), or make the manager with channels=2"
        raise ValueError(
            f"signal of shape {raw.shape}: this manager (channels={channels}) expects {expected}; {hint}"
        )
    return np.ascontiguousarray(x)


def _plain(value: Any) -> Any:
    """``value`` as the plain Python values the core takes (dicts with string keys, lists,
    strings, numbers, booleans, ``None``): numpy arrays and scalars as lists and numbers."""
    if isinstance(value, np.ndarray):
        # MATLAB values arrive as 1×1, 1×N or N×1 matrices (scipy.io.loadmat): a scalar or
        # a vector either way
        if value.size == 1:
            return _plain(value.item())
        if value.ndim == 2 and 1 in value.shape:
            return _plain(value.reshape(-1).tolist())
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, float) and not np.isfinite(value):
        raise ValueError(f"parameter value {value!r}: AFE parameters take finite numbers")
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    raise ValueError(f"parameter value {value!r} of type {type(value).__name__} is not supported")


def _non_finite(value: Any) -> bool:
    """Whether a parameter value holds a NaN or infinity (JSON has no such numbers)."""
    if isinstance(value, (float, np.floating)):
        return not np.isfinite(value)
    if isinstance(value, np.ndarray):
        return np.issubdtype(value.dtype, np.floating) and not bool(np.all(np.isfinite(value)))
    if isinstance(value, (list, tuple)):
        return any(_non_finite(v) for v in value)
    return False


def _plain_params(params: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
    if params is None:
        return {}
    if not isinstance(params, Mapping):
        raise ValueError("params must be a dict of AFE parameter names to values")
    for name, value in params.items():
        if _non_finite(value):
            raise ValueError(f"parameter '{name}' is {value!r}: AFE parameters take finite numbers")
    return {str(k): _plain(v) for k, v in params.items()}


class Manager:
    """A streaming front-end, as the AFE's ``manager``: place requests, feed chunks.

    ``fs``: input sampling rate in Hz. ``channels``: 1 (mono) or 2 (left, right).
    ``threads``: threads of the concurrent scheduler, the calling one among them
    (``None`` or 0: sequential; the numbers are the same either way). ``keep_history``:
    keep every output for :meth:`outputs`, as the AFE's data object does (turn off for
    endless streams); ``history_seconds``: keep only the last that many seconds of each
    output (a bounded history for long live runs; ``None``: everything).

    Processing releases the GIL, so managers in several Python threads run in parallel.
    """

    def __init__(
        self,
        fs: float,
        channels: int = 2,
        threads: Optional[int] = None,
        keep_history: bool = True,
        history_seconds: Optional[float] = None,
    ) -> None:
        if history_seconds is not None and not float(history_seconds) > 0:
            raise ValueError(f"history_seconds = {history_seconds}: expected a positive number of seconds, or None")
        self._m = _afe.Manager(
            float(fs), int(channels), int(threads or 0), bool(keep_history),
            None if history_seconds is None else float(history_seconds),
        )
        # request handle → name, for summaries
        self._names: Dict[int, str] = {}
        # the outputs' descriptions, rebuilt after any change of the graph
        self._described: Optional[Dict[str, Dict[str, Any]]] = None

    def _with_descriptions(self, arrays: Dict[str, np.ndarray]) -> Dict[str, Signal]:
        """The last chunk's arrays as signals, stamped with where they start."""
        if self._described is None:
            self._described = self._m.describe()
        clocks = self._m.frames()
        return {
            k: Signal(v, dict(self._described[k], first_frame=clocks[k]["first_frame"],
                              first_time_s=clocks[k]["first_time_s"]))
            for k, v in arrays.items()
        }

    @property
    def fs(self) -> float:
        """Input sampling rate in Hz."""
        return self._m.fs

    @property
    def channels(self) -> int:
        """Number of input channels (1 or 2)."""
        return self._m.channels

    @property
    def threads(self) -> int:
        """Worker threads of the concurrent scheduler (0: sequential executor)."""
        return self._m.threads

    def add_request(self, name: str, params: Optional[Mapping[str, Any]] = None) -> int:
        """Places request ``name`` with AFE parameters ``params``; returns its handle.

        Processors whose whole chain has equal parameters are shared with earlier
        requests. Raises ``ValueError`` for an unknown request or parameter, an ill-typed
        value (the message lists what is accepted), or a binaural request on mono input.
        """
        handle = self._m.add_request(str(name), _plain_params(params))
        self._names[handle] = str(name)
        self._described = None
        return handle

    def frames(self) -> Dict[str, Dict[str, Any]]:
        """Where the last chunk's new frames stand in the stream, per output:
        ``first_frame`` (index among all the frames the output has given, counting on
        across ``reset`` and ``modify_parameter``), ``first_time_s`` (seconds from the
        stream's start), ``frames`` and ``fs_hz``. Frame ``k`` of the chunk is at
        ``first_time_s + k / fs_hz``. An output whose framing restarts (placed, reset,
        rebuilt by ``modify_parameter``) at input sample ``s`` has its next frame at
        ``s / fs``, the AFE's time axis (first frame at the start)."""
        return self._m.frames()

    def request_outputs(self, handle: int) -> List[str]:
        """The names of request ``handle``'s outputs (keys of :meth:`process_chunk`'s and
        :meth:`outputs`' dicts), e.g. ``["ratemap_2_left", "ratemap_2_right"]`` for a
        second ratemap with other parameters. Raises ``KeyError`` for an unknown handle."""
        return list(self._m.request_outputs(int(handle)))

    def request_parameters(self, handle: int) -> Dict[str, Any]:
        """The parameters every processor of request ``handle``'s chain runs with, defaults
        included (the AFE's ``getParameterSummary``). Raises ``KeyError`` for an unknown
        handle."""
        return self._m.request_parameters(int(handle))

    def remove_request(self, handle: int) -> None:
        """Removes a request; its processors go when no other request uses them.
        Raises ``KeyError`` for an unknown handle."""
        self._described = None
        self._m.remove_request(int(handle))
        self._names.pop(int(handle), None)

    def modify_parameter(self, name: str, value: Any, handle: Optional[int] = None) -> None:
        """Changes AFE parameter ``name`` between chunks, as the AFE's ``modifyParameter``:
        the processors that use it are rebuilt and reset, and so is everything computed
        from them. ``handle`` limits the change to one request's processors; by default
        every request using the parameter is changed. Raises ``ValueError`` if no request
        uses it or the value is invalid."""
        self._described = None
        if handle is not None:
            self._m.modify_parameter(int(handle), str(name), _plain(value))
            return
        changed = False
        for h in self._m.handles():
            try:
                self._m.modify_parameter(h, str(name), _plain(value))
                changed = True
            except ValueError as e:
                if "uses this parameter" not in str(e):
                    raise  # an invalid value or a fixed parameter: not to be skipped
        if not changed:
            raise ValueError(f"no request in place uses parameter '{name}'")

    def process_chunk(self, x: Audio) -> Dict[str, Signal]:
        """Processes the next chunk (``[samples]`` or ``[samples, 2]``), keeping every
        processor's state; returns the new output of every request since the last call,
        each a :class:`Signal` whose ``t_s`` gives its rows' times in the stream."""
        return self._with_descriptions(self._m.process_chunk(_as_channels(x, self.channels)))

    def process_signal(self, x: Audio) -> Dict[str, Signal]:
        """Processes a whole signal from a fresh state (as the AFE's ``processSignal``)
        and returns the output of every request. Ctrl-C, or :meth:`cancel` from another
        thread, stops it within a block (KeyboardInterrupt)."""
        return self._with_descriptions(self._m.process_signal(_as_channels(x, self.channels)))

    def cancel(self) -> None:
        """Stops this manager's ``process_signal`` that runs now (in another thread): it
        raises KeyboardInterrupt. Other managers run on; without such a call, nothing
        happens."""
        self._m.cancel()

    def set_head_yaw(self, t_s: float, yaw_deg: float) -> None:
        """Reports the head's yaw ``yaw_deg`` (deg, positive to the left) at ``t_s`` (s
        since the processors started: the first chunk, or the last ``reset``; a
        ``process_signal`` starts at 0). The ``tracking`` request reads it at each
        frame's centre, between the reports along the shorter way round, the newest one
        held until the next; times must increase (``ValueError`` otherwise). Callable
        from any thread, also while a chunk or a whole signal runs."""
        self._m.set_head_yaw(float(t_s), float(yaw_deg))

    def prepare(self, max_chunk: int) -> None:
        """Sizes every buffer for chunks of up to ``max_chunk`` samples before the first
        chunk, so that processing allocates nothing from the first chunk on (for live
        audio). Only before the first chunk or after ``reset``."""
        self._m.prepare(int(max_chunk))

    def reset(self) -> None:
        """Returns every processor to its initial state and clears the history."""
        self._m.reset()

    def outputs(self, handle: Optional[int] = None) -> Dict[str, Signal]:
        """Everything computed since creation, the last ``reset`` or ``process_signal``,
        as the AFE's data object keeps it: editing one request never drops the frames
        computed for the others. After ``modify_parameter`` the edited request's outputs go
        on in the same arrays, their ``meta["segments"]`` listing each parameter
        setting's first row, time and parameters; an output whose shape changed (e.g.
        ``fb_nChannels``), or whose request was removed, keeps its earlier rows under
        ``"<name>@<time>"`` (the time in s where its next row would have started). ``handle``: only that request's current outputs
        (``KeyError`` for an unknown handle)."""
        wanted = None if handle is None else set(self.request_outputs(handle))
        arrays, meta = self._m.outputs()
        return {k: v for k, v in _signals(arrays, meta).items()
                if wanted is None or k in wanted}

    def info(self) -> Dict[str, Dict[str, Any]]:
        """For each output name: ``kind`` (``time-domain``, ``time-frequency``,
        ``correlation``, ``modulation``, ``feature``, ``spectrum``, ``binary-mask``,
        ``duet-histogram``),
        ``afe_class`` (the AFE's signal class), ``axes`` (array axis names), ``dtype``
        (``float64``, or ``complex128`` for spectra), ``fs_hz`` (output rate; frame rate
        of framed signals), ``audio_fs_hz``, ``cf_hz`` (channel centre frequencies; bin
        frequencies of a spectrum), ``lags_s`` (correlation lags, s), ``mod_cf_hz``
        (modulation centre frequencies), ``features`` (feature names, in column order),
        ``alpha`` and ``delta_samples`` (DUET histogram bin centres: attenuation, and delay
        in samples) and ``frame_shape`` (shape of one time step)."""
        return self._m.info()

    def __repr__(self) -> str:
        """``afe.Manager(fs=..., channels=..., threads=...): N requests`` and the
        :func:`afe.summary` of its graph (each request's chain with the parameters that
        are not the defaults)."""
        from .summary import manager_text

        return manager_text(self, repr(self._m))


def _cores() -> int:
    """The cores this process may run on: the default thread count of a whole signal."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def process(
    signal: Audio,
    fs: Optional[float],
    requests: Requests,
    params: Optional[Mapping[str, Any]] = None,
    chunk: Optional[int] = None,
    threads: Optional[int] = None,
    keep: str = "requested",
    dtype: str = "float64",
) -> Dict[str, Signal]:
    """Computes ``requests`` on a whole signal and returns ``{name: Signal}``.

    ``signal``: ``[samples]`` (mono), ``[samples, 2]`` (left, right), or the path of a WAV
    file (then ``fs`` may be ``None``; if given it must match the file's). ``requests``:
    request names (a list, or one comma-separated string), or ``(name, params)`` pairs
    whose own parameters go over ``params`` (as :func:`afe.stream` takes them), so that
    one call holds, e.g., two ratemaps with different parameters
    (``[("ratemap", {"fb_nChannels": 16}), ("ratemap", {"fb_nChannels": 8}), "ild"]``:
    ``ratemap_left``, ``ratemap_2_left``, ... as :meth:`Manager.request_outputs` names
    them); an error about one item names it (``requests[1]: ...``). ``params``:
    AFE parameter names to values, shared by every request. ``chunk``: feed the signal in
    chunks of this many samples, as a stream would (same result wherever the AFE is
    chunk-invariant). ``threads``: scheduler threads, the caller among them (``None``:
    the machine's cores; 0: the sequential executor); every choice gives the same numbers.
    ``dtype="float32"`` stores the values (computed in float64) rounded to float32
    (complex64 for spectra): half the memory, as ``afe extract --dtype f32`` writes them.
    ``keep="all"`` also returns every intermediate signal the requests were computed
    through (``time_left``, ``filterbank_left``, ``innerhaircell_left``, ...), as the
    AFE's data object holds them and as ``afe extract --all`` saves them.

    The arrays are those of ``afe extract``: ``ratemap_left``, ``ild_mono``, ... float64,
    each an :class:`afe.Signal` with its description (the ``.npz``'s ``afe_metadata``).
    """
    if keep not in ("requested", "all"):
        raise ValueError(f"keep must be 'requested' or 'all', got {keep!r}")
    items = []
    for i, (name, own) in enumerate(_request_items(requests)):
        try:
            items.append((name, _plain_params(own)))
        except ValueError as e:
            raise ValueError(f"requests[{i}] ({name!r}): {e}") from None
    if chunk is not None and int(chunk) < 1:
        raise ValueError(f"chunk = {chunk}: expected a positive number of samples")
    settings = (
        items,
        _plain_params(params),
        None if chunk is None else int(chunk),
        _cores() if threads is None else int(threads),
        keep == "all",
        str(dtype),
    )
    if isinstance(signal, (str, os.PathLike)):
        # decoded block by block in Rust: a long file is never held whole
        arrays, meta = _afe.process_file(
            os.fspath(signal), None if fs is None else float(fs), *settings
        )
        return _signals(arrays, meta)
    if fs is None:
        raise ValueError("fs is required when the signal is an array")
    x = _as_channels(signal)
    if x.shape[0] == 0:
        raise ValueError("the signal is empty")
    if x.shape[1] == 1:
        binaural = {r["name"] for r in _catalog() if r["binaural"]}
        for i, (name, _) in enumerate(items):
            if name in binaural:
                raise ValueError(
                    f"requests[{i}]: request '{name}' needs a binaural (two-channel) input, but the "
                    f"signal has shape {np.shape(signal)}: give [samples, 2] (left, right), e.g. "
                    f"np.column_stack([left, right]) (shape ({x.shape[0]}, 2))"
                )
    arrays, meta = _afe.process(x, float(fs), *settings)
    return _signals(arrays, meta)


def raa(
    ear_signals: Audio, fs: Optional[float] = None, **constants: float
) -> Tuple[Dict[str, float], Dict[str, Any]]:
    """The AFE's Room Acoustic Analyzer: ``[par, psi] = afeRAA(earSignals, fs, parConf)``.

    van Dorp Schuitman's model of room-acoustic perception on the AFE's processors: the
    headphone filter, the ``adaptation`` request (16 gammatone bands, 167.8 to 1836.4 Hz,
    ``breebart`` hair cell, ``adt_vandorpschuitman`` loops), Psi (the adaptation output
    low-passed over 20 ms) split per ear and band into a direct and a reverberant stream
    by its peaks and dips, and the ITD per 50-ms frame.

    ``ear_signals``: ``[samples, 2]`` (left, right; full scale 1), or the path of a
    binaural WAV file (``fs`` then may be ``None``). ``constants``: afeRAA's ``parConf``
    by name (``mu_psi``, ``mu_psi_dip``, ``T_min``, ``a_P_REV``, ``b_P_REV``, ``a_P_CLA``,
    ``b_P_CLA``, ``mu_ASW``, ``nu_ASW``, ``a_P_ASW``, ``b_P_ASW``, ``mu_LEV``, ``nu_LEV``,
    ``a_P_LEV``, ``b_P_LEV``), the AFE's values by default; an unknown name is a
    ``ValueError`` naming the closest one.

    Returns ``(par, psi)``. ``par``: each predictor as a float, under afeRAA's names:
    ``BL`` and ``FL`` (levels of the background and foreground streams, MU = model
    units), ``sREV`` (reverberance, scaled 0..1; ``BL`` is the unscaled one), ``pClar``
    and ``sClar`` (clarity, ``FL/BL`` and scaled), ``Llow`` (level of the bands from 168
    to 387 Hz, MU), ``ITDf`` and ``ITDb`` (ITD fluctuations of the foreground and the
    background), ``pASW``/``sASW`` (apparent source width) and ``pLEV``/``sLEV``
    (listener envelopment), unscaled and scaled. ``psi``: ``PsiL``, ``PsiR`` and their
    streams ``PsiLdir``, ``PsiRdir``, ``PsiLrev``, ``PsiRrev`` (``[sample, band]``, MU),
    ``ITD``, ``ITDdir``, ``ITDrev`` (``[frame, band]``), ``f`` (band centre frequencies,
    Hz), ``t_psi`` (``(1..N)/fs``, s), ``t_itd`` (frame starts, s), ``fs`` (Hz),
    ``numSamples``, ``numBands``, ``itdNumFrames``.

    The ITD is in afeRAA's unit, the lag in samples times 0.025 s (``fs/40`` times the
    delay in seconds, 400x at 16 kHz; positive when the right ear leads), and so are
    ``ITDf`` and ``ITDb``. Raises ``ValueError`` for input afeRAA cannot take: not two
    channels, empty, NaN, ``fs`` at most 8 kHz, shorter than 75 ms, or a band with no
    sample beyond its peak or dip threshold (where afeRAA itself fails).
    """
    for name, value in constants.items():
        if _non_finite(value):
            raise ValueError(f"constant '{name}' is {value!r}: the RAA takes finite numbers")
    x, fs = _signal_at_rate(ear_signals, fs)
    return _afe.raa(x, fs, _plain_params(constants))


def _signal_at_rate(signal: Audio, fs: Optional[float]) -> Tuple[np.ndarray, float]:
    """``[samples, channels]`` float64 and its rate, from an array and ``fs`` or from the
    path of a WAV file (whose rate ``fs``, if given, must equal)."""
    if isinstance(signal, (str, os.PathLike)):
        x, file_fs = read_wav(signal)
        if fs is not None and float(fs) != file_fs:
            raise ValueError(f"fs = {fs} Hz, but '{os.fspath(signal)}' is sampled at {file_fs} Hz")
        return _as_channels(x), file_fs
    if fs is None:
        raise ValueError("fs is required when the signal is an array")
    return _as_channels(signal), float(fs)


def locate(
    ear_signals: Audio,
    fs: Optional[float] = None,
    head: str = "kemar",
    sources: Optional[int] = None,
    head_yaw: Any = None,
    track: bool = False,
) -> Dict[str, Any]:
    """Where the sources of a binaural signal are, for the head that heard it (as
    ``afe locate``; docs/localisation.md).

    ``ear_signals``: ``[samples, 2]`` (left, right) or the path of a binaural WAV file.
    ``head``: ``"kemar"`` (the MIT KEMAR set from Debian's libmysofa1),
    ``"sphere:radius=M[,ears=DEG]"`` (a rigid sphere; ``"sphere"``: the 15-cm ball) or
    the path of a SimpleFreeFieldHRIR ``.sofa`` file (:func:`heads` lists the built-in
    ones). ``sources``: how many to report (default: those at least 0.9 as salient as
    the first). ``head_yaw``: the head's yaw over time, ``[points, 2]`` rows of
    ``(t_s, yaw_deg)`` (yaw positive to the left, times increasing): azimuths are then in
    the world (world = relative + yaw), and a turning head tells front from back.

    Returns a dict: ``sources`` (a list of ``{"azimuth_deg", "salience"}``, most salient
    first; azimuth 0 = front, 90 = left, in [0, 360)), per frame ``t_s`` (centres, s),
    ``active`` (bool), ``azimuth_deg`` (its best direction) and ``yaw_deg``, and the score
    grid ``azimuths_deg`` with the active frames' ``mean_score``. With ``track``, also
    ``tracked``: the sources tracked over time in the world (a Bayes filter over world
    azimuth that carries the head's turns, so a turn tells front from back), at 6 Hz, a
    list of ``{"t_s", "yaw_deg", "tracks": [{"id", "azimuth_deg", "uncertainty_deg",
    "mass", "velocity_deg_s", "seen_s", "resolved"}, ...], "suggested_turn"}``, the turn
    (``None``, or ``{"turn_deg", "target_yaw_deg", "why": "mirror", "ids"}`` or
    ``{..., "why": "behind", "id"}``, for a neck turning ±90 degrees) that would tell
    front from back. Raises ``ValueError``
    naming the problem: an unknown head, a bad SOFA file, not two channels, NaN, a signal
    shorter than a 40-ms frame, a yaw track that is not ``[points, 2]`` with increasing
    times.
    """
    if sources is not None and (not isinstance(sources, int) or sources < 1):
        raise ValueError(f"sources = {sources!r}: a number of sources, at least 1")
    x, fs = _signal_at_rate(ear_signals, fs)
    yaw = None
    if head_yaw is not None:
        yaw = np.ascontiguousarray(np.asarray(head_yaw, dtype=np.float64))
        if yaw.ndim != 2 or yaw.shape[1] != 2:
            raise ValueError(
                f"head_yaw of shape {yaw.shape}: rows of (t_s, yaw_deg), [points, 2]"
            )
    return _afe.locate(x, fs, str(head), sources, yaw, bool(track))


def render(x: Any, fs: float, azimuth_deg: float, head: str = "sphere") -> np.ndarray:
    """The mono signal ``x`` at ``fs`` Hz as the two ears of ``head`` hear it from
    ``azimuth_deg`` (0 = front, 90 = left): ``[samples, 2]``. Any head renders at any
    rate below its Nyquist frequency; a measured head takes its nearest direction."""
    mono = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if mono.ndim != 1:
        raise ValueError(f"x of shape {mono.shape}: render takes a mono signal [samples]")
    return _afe.render(mono, float(fs), str(head), float(azimuth_deg))


def transfer(freqs_hz: Any, azimuth_deg: float, head: str = "sphere") -> np.ndarray:
    """The transfer functions of ``head`` to the left and the right ear from
    ``azimuth_deg`` (0 = front, 90 = left) at each of ``freqs_hz``, relative to the free
    field at the head's centre, in the DFT's sign convention (a delay is
    ``exp(-2j*pi*f*tau)``): complex ``[freqs, 2]``. A measured head gives its nearest
    direction, from 0 Hz to its Nyquist frequency; the sphere its Duda-Martens series."""
    freqs = np.ascontiguousarray(np.asarray(freqs_hz, dtype=np.float64))
    if freqs.ndim != 1:
        raise ValueError(f"freqs_hz of shape {freqs.shape}: a vector of frequencies, Hz")
    return _afe.transfer(freqs, str(head), float(azimuth_deg))


def heads() -> List[Tuple[str, str]]:
    """The heads :func:`locate` and :func:`render` name without a file: ``(name,
    description)`` pairs."""
    return [(name, description) for name, description in _afe.heads()]


from .corpus import Store, batch, open_store  # noqa: E402  (uses _plain_params above)
from .saving import load, save  # noqa: E402
from .summary import summary  # noqa: E402  (uses Manager and _catalog above)
from .plot import plot  # noqa: E402  (calls process above)
from .frames import Frames, stream  # noqa: E402  (uses Manager and read_wav above)
from .remote import Audio, AudioBlock, Remote, RemoteError, Subscription, connect  # noqa: E402  (uses _plain_params)
