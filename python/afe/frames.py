"""Blocks of a stream: :class:`Frames`, one block's new frames of every requested output,
as a remote subscription (:func:`afe.connect`) and the local iterator :func:`afe.stream`
both give them.

>>> import afe, numpy as np
>>> fs = 16000
>>> x = np.random.default_rng(0).standard_normal((fs // 2, 2)) * 0.1
>>> blocks = list(afe.stream(x, ["ratemap"], {"fb_nChannels": 8}, fs_hz=fs))
>>> len(blocks), blocks[0].input_frames, sorted(blocks[0])
(50, 160, ['ratemap_left', 'ratemap_right'])
>>> blocks[3]["ratemap_left"].first_frame, blocks[3]["ratemap_left"].shape
(2, (1, 8))
"""

from __future__ import annotations

import os
import time
from typing import (
    Any,
    Dict,
    ItemsView,
    Iterator,
    KeysView,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
    ValuesView,
    cast,
)

import numpy as np

from .signal import Signal

#: What :func:`afe.stream` and :meth:`afe.Remote.subscribe` take as requests: names
#: (a list, or one comma-separated string), or ``(name, params)`` pairs.
Requests = Union[str, Sequence[str], Sequence[Tuple[str, Optional[Mapping[str, Any]]]]]


def request_items(requests: Requests) -> List[Tuple[str, Optional[Dict[str, Any]]]]:
    """``[(name, own params or None)]`` from request names (a list, or one comma-separated
    string) or ``(name, params)`` pairs. Raises ``ValueError`` naming the item that is
    wrong (``requests[1]: ...``), or when no request is given."""
    items: Sequence[Union[str, Tuple[str, Optional[Mapping[str, Any]]]]]
    if isinstance(requests, str):
        items = requests.split(",")
    elif isinstance(requests, tuple) and len(requests) == 2 and isinstance(requests[0], str) and (
        requests[1] is None or isinstance(requests[1], Mapping)
    ):
        # one (name, params) pair on its own: the checks above are what the cast says
        items = [cast(Tuple[str, Optional[Mapping[str, Any]]], requests)]
    else:
        items = requests
    out: List[Tuple[str, Optional[Dict[str, Any]]]] = []
    own: Optional[Mapping[str, Any]]
    for i, r in enumerate(items):
        if isinstance(r, str):
            name, own = r, None
        elif isinstance(r, (tuple, list)) and len(r) == 2 and isinstance(r[0], str):
            name, own = r[0], r[1]
            if own is not None and not isinstance(own, Mapping):
                raise ValueError(
                    f"requests[{i}] ({name!r}): its parameters must be a dict, got {own!r}"
                )
        else:
            raise ValueError(
                f"requests[{i}] = {r!r}: give a request name or a (name, params) pair, e.g. "
                "'ratemap' or ('ratemap', {'fb_nChannels': 16})"
            )
        name = name.strip()
        if not name:
            continue
        out.append((name, None if own is None else dict(own)))
    if not out:
        raise ValueError("no request given, e.g. ['ratemap', 'ild']")
    return out


def request_list(
    requests: Requests, params: Optional[Mapping[str, Any]] = None
) -> List[Tuple[str, Dict[str, Any]]]:
    """``[(name, params)]`` from names (a list or a comma-separated string), all with
    ``params``, or from ``(name, params)`` pairs (their own parameters over ``params``).
    Raises ``ValueError`` when no request is given or an entry is neither."""
    return [(name, {**dict(params or {}), **(own or {})}) for name, own in request_items(requests)]


class Frames:
    """One block of a stream: the new frames of every output of a subscription (remote)
    or of the requests of :func:`afe.stream` (local), computed from that block's audio.

    A read-only mapping from output names (``ratemap_left``, ``ild_mono``, ...) to
    :class:`afe.Signal` arrays shaped ``[rows, *frame_shape]`` (float64, complex128 for
    spectra) with their descriptions; ``signal.first_frame`` is the index of its row 0
    among all the frames the output has given, and ``signal.t_s`` the rows' times in
    seconds from the start of the stream. A block may hold no row of a slow output.

    Attributes:
        seq: the block's message number (remote: on its subscription, from 0; local: the
            block's index).
        first_input_frame: index of the block's first audio frame in the stream (remote:
            on the server's port, counting from the server's start).
        input_frames: audio frames in the block.
        t_ns: Unix time in ns at which the block's last audio frame was on the server's
            port (local: when the block was handed to the manager).
        lost_messages: messages lost just before this one (always 0 locally).
        signals: the outputs, in the subscription's (requests') order.
    """

    __slots__ = ("seq", "first_input_frame", "input_frames", "t_ns", "lost_messages", "signals")

    def __init__(
        self,
        seq: int,
        first_input_frame: int,
        input_frames: int,
        t_ns: int,
        lost_messages: int,
        signals: Dict[str, Signal],
    ) -> None:
        self.seq = int(seq)
        self.first_input_frame = int(first_input_frame)
        self.input_frames = int(input_frames)
        self.t_ns = int(t_ns)
        self.lost_messages = int(lost_messages)
        self.signals: Dict[str, Signal] = dict(signals)

    def __getitem__(self, key: str) -> Signal:
        """The new frames of output ``key``; ``KeyError`` (naming the keys) if absent."""
        try:
            return self.signals[key]
        except KeyError:
            raise KeyError(f"{key!r}: this block holds {', '.join(self.signals)}") from None

    def __iter__(self) -> Iterator[str]:
        """The output names, in order."""
        return iter(self.signals)

    def __len__(self) -> int:
        """Number of outputs."""
        return len(self.signals)

    def __contains__(self, key: object) -> bool:
        """Whether output ``key`` is in the block."""
        return key in self.signals

    def keys(self) -> KeysView[str]:
        """The output names, in order."""
        return self.signals.keys()

    def values(self) -> ValuesView[Signal]:
        """The outputs' new frames, in order."""
        return self.signals.values()

    def items(self) -> ItemsView[str, Signal]:
        """``(name, Signal)`` pairs, in order."""
        return self.signals.items()

    def get(self, key: str, default: Any = None) -> Any:
        """Output ``key``'s new frames, or ``default``."""
        return self.signals.get(key, default)

    @property
    def latency_s(self) -> float:
        """Seconds from the moment the block's last audio frame was on the server's port
        to now (meaningful when both run on one clock, e.g. on the same host)."""
        return time.time_ns() * 1e-9 - self.t_ns * 1e-9

    def __repr__(self) -> str:
        shapes = ", ".join(f"{k}: {list(v.shape)}" for k, v in self.signals.items())
        return (
            f"afe.Frames(seq {self.seq}, input frames {self.first_input_frame}"
            f"+{self.input_frames}, lost {self.lost_messages}; {shapes})"
        )


def _as_ears(source: Any) -> np.ndarray:
    """``[time, ears]`` from ``[time]``, ``[time, ears]`` or ``[ears, time]``."""
    from . import _as_channels

    x = np.asarray(source)
    if x.ndim == 2 and x.shape[0] in (1, 2) and x.shape[1] not in (1, 2):
        x = x.T
    return _as_channels(x)


def stream(
    source: Any,
    requests: Requests,
    params: Optional[Mapping[str, Any]] = None,
    block_ms: float = 10.0,
    fs_hz: Optional[float] = None,
) -> Iterator[Frames]:
    """Streams audio block by block through a local :class:`afe.Manager`, yielding
    one :class:`Frames` per block: the same blocks a subscription to ``afe serve``
    gives, computed here.

    ``source``: a WAV file's path; an array ``[time]``, ``[time, ears]`` or
    ``[ears, time]`` (then ``fs_hz`` is required; for a file it is checked if given);
    or a server's raw audio, :meth:`afe.Remote.audio` (its blocks are the server's,
    ``block_ms`` is not used, and each :class:`Frames` counts the audio messages lost
    before it; the front-end runs on the samples received, as a device's would after an
    overrun). ``requests``: request names (a list or a comma-separated string), all
    with ``params``, or ``(name, params)`` pairs. ``block_ms``: the block, in ms
    (``round(block_ms * fs / 1000)`` frames; the last block holds what is left).

    The outputs are computed chunk by chunk with :meth:`afe.Manager.process_chunk`, so
    their concatenated rows equal :func:`afe.process`'s arrays for a chunk-invariant
    front-end (all of afe's requests). Raises ``ValueError`` for an unknown request or
    parameter, a bad source or block.
    """
    from . import Manager, read_wav
    from .remote import Audio

    if isinstance(source, Audio):
        if fs_hz is not None and float(fs_hz) != source.fs_hz:
            raise ValueError(f"fs_hz = {fs_hz} Hz, but the server streams at {source.fs_hz:g} Hz")
        fs, ears = source.fs_hz, source.ears
        blocks: Iterator[Tuple[int, np.ndarray, int]] = (
            (b.first_frame, b.samples, b.lost_messages) for b in source
        )
    else:
        if isinstance(source, (str, os.PathLike)):
            x, fs = read_wav(source)
            if fs_hz is not None and float(fs_hz) != fs:
                raise ValueError(f"fs_hz = {fs_hz} Hz, but the file is at {fs:g} Hz")
            x = _as_ears(x)
        else:
            if fs_hz is None:
                raise ValueError("fs_hz is required when the source is an array")
            fs = float(fs_hz)
            x = _as_ears(source)
        block = int(round(float(block_ms) * fs / 1000.0))
        if block < 1:
            raise ValueError(f"block_ms = {block_ms}: a block of {block} frames at {fs:g} Hz")
        ears = x.shape[1]
        blocks = ((start, x[start : start + block], 0) for start in range(0, x.shape[0], block))
    mgr = Manager(fs, ears, keep_history=False)
    keys: List[str] = []
    for name, p in request_list(requests, params):
        for k in mgr.request_outputs(mgr.add_request(name, p)):
            if k not in keys:
                keys.append(k)
    # the requests are placed (and their errors raised) here, not at the first block
    return _run(mgr, blocks, keys)


def _run(mgr: Any, blocks: Iterator[Tuple[int, np.ndarray, int]], keys: List[str]) -> Iterator[Frames]:
    """The blocks of :func:`stream`, from ``(first frame, samples, messages lost before)``."""
    for seq, (start, chunk, lost) in enumerate(blocks):
        t_ns = time.time_ns()
        out = mgr.process_chunk(chunk)
        signals: Dict[str, Signal] = {}
        for k in keys:
            s = out[k]
            if s.meta.get("dtype") == "complex128" and not np.iscomplexobj(s):
                # a block without rows of a spectrum comes as float64: keep its dtype
                s = Signal(np.asarray(s).astype(np.complex128), s.meta)
            signals[k] = s
        yield Frames(seq, start, chunk.shape[0], t_ns, lost, signals)
