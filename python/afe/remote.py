"""Remote clients of ``afe serve``: subscribe over `Zenoh <https://zenoh.io>`_ to the
representations a server computes from its live audio, block by block.

>>> import afe                                                      # doctest: +SKIP
>>> with afe.connect("tcp/127.0.0.1:7447") as robot:                # doctest: +SKIP
...     with robot.subscribe(["ratemap", "ild"], {"fb_nChannels": 16}) as sub:
...         for frames in sub:
...             frames["ild_mono"]          # this block's new frames: [rows, 16]

Each block of the server's stream arrives as an :class:`afe.Frames`, the class
:func:`afe.stream` yields locally: the values are the server's, bit for bit. Requests
equal to ones the server already computes (its own, or other clients') share their
processors; a new one starts from the server's next block.

Needs the ``eclipse-zenoh`` package (the version of the server's Zenoh, 1.10.2).
The protocol (keys under ``afe/<name>/``, the binary messages) is described in the Rust
crate ``afe-net`` (``afe_net`` and ``afe_net::wire``, whose reader decodes the messages
here too).
"""

from __future__ import annotations

import json
import math
import re
import threading
import time
import weakref
from typing import Any, Dict, Generic, List, Mapping, Optional, Tuple, TypeVar

import numpy as np

from . import _afe
from .frames import Frames, Requests, request_list
from .signal import Signal

#: Where ``afe serve`` listens unless told otherwise.
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
#: The wire version this client reads.
WIRE_VERSION = 1

_Block = TypeVar("_Block")
_Self = TypeVar("_Self", bound="_Receiver[Any]")
_NAME = re.compile(r"[A-Za-z0-9_-]+\Z")
# how often a waiting recv looks for a block (zenoh's Python handlers have no timed recv)
_POLL_S = 0.001


class RemoteError(RuntimeError):
    """The server refused a query (``message`` holds its reason, e.g. an unknown request
    or a bad parameter value), or sent a message this client cannot read."""

    def __init__(self, message: str, server: Optional[str] = None) -> None:
        self.message = message
        self.server = server
        super().__init__(message if server is None else f"the server '{server}' refused: {message}")


def _zenoh() -> Any:
    try:
        import zenoh
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            "afe's remote client needs Zenoh's Python package: pip install eclipse-zenoh==1.10.2"
        ) from e
    return zenoh


def _capacity(capacity: int) -> int:
    """A receiver's queue length, checked: at least one block."""
    if int(capacity) < 1:
        raise ValueError(f"capacity = {capacity}: keep at least one block")
    return int(capacity)


def _json_body(payload: Any, what: str) -> Any:
    try:
        return json.loads(payload.to_bytes())
    except ValueError as e:
        raise RemoteError(f"malformed reply on {what}: {e}") from None


def connect(endpoint: str = DEFAULT_ENDPOINT, name: Optional[str] = None, timeout: float = 10.0) -> Remote:
    """Connects to the ``afe serve`` server listening on ``endpoint`` (a Zenoh endpoint,
    e.g. ``tcp/127.0.0.1:7447``) and returns a :class:`Remote`.

    ``name``: the server's name (``afe serve --name``); ``None`` finds it, when exactly
    one server answers at the endpoint. ``timeout``: seconds a query waits for the
    server's reply.

    Raises ``ConnectionError`` when nothing listens at the endpoint, no server answers
    (or several do and none is named), ``ValueError`` for a name that cannot be one,
    and :class:`RemoteError` when the server refuses (its stream has not started).
    """
    return Remote(endpoint, name, timeout)


class Remote:
    """A connection to an ``afe serve`` server (see :func:`connect`): a Zenoh session
    (a peer that connects to the endpoint and listens nowhere, multicast scouting off).
    Its subscriptions go when it is closed or when this process ends (the server watches
    the client's liveliness token). A context manager: ``with afe.connect(...) as
    robot:`` closes it on leaving.

    Attributes: ``endpoint``; ``name``, the server's; ``id``, this client's (its Zenoh
    session's id); ``catalogue``, the server's (``fs_hz``, ``ears``, ``block_frames``,
    ``wire_version`` and ``requests``, as ``afe list --json`` gives them).
    """

    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, name: Optional[str] = None, timeout: float = 10.0) -> None:
        zenoh = _zenoh()
        if name is not None and not _NAME.match(name):
            raise ValueError(f"server name {name!r}: use letters, digits, '-' and '_' only")
        if not timeout > 0:
            raise ValueError(f"timeout = {timeout}: give a positive number of seconds")
        self._zenoh = zenoh
        self._timeout = float(timeout)
        self._closed = False
        self._lock = threading.Lock()
        # the secret the server gave with this client's first subscription: every later
        # subscription and cancellation carries it (the id alone is public); held while a
        # subscription is asked for, so that two first ones are not asked for at once
        self._secret: Optional[str] = None
        self._secret_lock = threading.Lock()
        self._receivers: weakref.WeakSet[_Receiver[Any]] = weakref.WeakSet()
        self._gone = False
        self.endpoint: str = endpoint
        # a peer that listens nowhere, as the Rust client: a Zenoh *client* is not told
        # when the server's liveliness token goes with its process (SIGKILL, a lost link)
        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("listen/endpoints", "[]")
        config.insert_json5("connect/endpoints", json.dumps([endpoint]))
        config.insert_json5("scouting/multicast/enabled", "false")
        try:
            self._session = zenoh.open(config)
        except zenoh.ZError as e:
            raise ConnectionError(f"cannot reach an afe server at {endpoint}: {e}") from None
        try:
            self.name: str = name if name is not None else self._discover()
            self.catalogue: Dict[str, Any] = self._query("catalogue")
            if self.catalogue.get("wire_version") != WIRE_VERSION:
                raise RemoteError(
                    f"the server '{self.name}' speaks wire version "
                    f"{self.catalogue.get('wire_version')}; this client reads {WIRE_VERSION}"
                )
            self.id: str = str(self._session.zid())
            # the server releases this client's subscriptions when this token goes
            self._token = self._session.liveliness().declare_token(self._key(f"client/{self.id}"))
            # the server's token, watched through a channel read where a block is awaited
            # (a Python callback would run on a thread that holds the interpreter open at
            # exit); a ring, so that unread changes never hold up Zenoh's reception
            self._watch = self._session.liveliness().declare_subscriber(
                self._key("server"), zenoh.handlers.RingChannel(8)
            )
        except BaseException:
            self._session.close()
            raise

    def _key(self, what: str) -> str:
        return f"afe/{self.name}/{what}"

    def _discover(self) -> str:
        """The name of the one server answering at the endpoint."""
        names = set()
        replies = self._session.get(
            "afe/*/catalogue",
            timeout=self._timeout,
            consolidation=self._zenoh.ConsolidationMode.NONE,
        )
        for reply in replies:
            sample = reply.ok
            if sample is None:
                continue
            try:
                server = json.loads(sample.payload.to_bytes()).get("server")
            except (ValueError, AttributeError):
                server = None
            key = str(sample.key_expr)
            if not isinstance(server, str):
                # the name from the reply's key, when it is a concrete one
                server = key[len("afe/") : -len("/catalogue")] if key.startswith("afe/") else ""
            if _NAME.match(server):
                names.add(server)
        if not names:
            if not self._session.info.peers_zid():
                raise ConnectionError(f"cannot reach an afe server at {self.endpoint}: nothing answers there")
            raise ConnectionError(f"no afe server answered at {self.endpoint}")
        if len(names) > 1:
            raise ConnectionError(
                f"several afe servers answer at {self.endpoint} ({', '.join(sorted(names))}): name one"
            )
        return names.pop()

    def _query(self, what: str, body: Optional[Mapping[str, Any]] = None, timeout: Optional[float] = None) -> Any:
        """Sends a query to ``afe/<name>/<what>``; returns its reply's JSON. Raises
        :class:`RemoteError` for an error reply, ``ConnectionError`` for none."""
        key = self._key(what)
        wait = self._timeout if timeout is None else timeout
        try:
            replies = self._session.get(key, payload=None if body is None else json.dumps(body), timeout=wait)
            for reply in replies:
                if reply.ok is not None:
                    return _json_body(reply.ok.payload, key)
                raw = reply.err.payload.to_bytes() if reply.err is not None else b""
                try:
                    message = str(json.loads(raw)["error"])
                except (ValueError, KeyError, TypeError):
                    # not the server's {"error": ...}: Zenoh's own (a timeout)
                    text = raw.decode("utf-8", "replace") or "no reply"
                    raise ConnectionError(f"query on {key}: {text} (after {wait:g} s)") from None
                raise RemoteError(message, self.name)
        except self._zenoh.ZError as e:
            raise ConnectionError(f"query on {key}: {e}") from None
        if not self._session.info.peers_zid():
            raise ConnectionError(f"cannot reach an afe server at {self.endpoint}: nothing answers there")
        raise ConnectionError(f"no reply on {key} within {wait:g} s: is the server '{self.name}' running?")

    @property
    def fs_hz(self) -> float:
        """Sampling rate of the server's stream, Hz."""
        return float(self.catalogue["fs_hz"])

    @property
    def ears(self) -> int:
        """Channels of the server's stream (1 or 2)."""
        return int(self.catalogue["ears"])

    @property
    def block_frames(self) -> int:
        """Audio frames per block of the server's stream."""
        return int(self.catalogue["block_frames"])

    @property
    def platform(self) -> Optional[Dict[str, Any]]:
        """The robot's platform descriptor, as ``afe serve --platform`` published it
        (docs/platform.md: its parts, joints, microphones and head model); ``None`` where
        the server was given none."""
        p = self.catalogue.get("platform")
        return dict(p) if isinstance(p, dict) else None

    def set_head_yaw(self, t_s: float, yaw_deg: float) -> None:
        """Reports the robot head's yaw ``yaw_deg`` (deg, positive to the left) at ``t_s``
        (s of the server's stream) on ``afe/<name>/head/yaw``, as a motor controller
        would: the server's ``tracking`` turns its azimuths into the world's by it. The
        server refuses (and counts) a time that does not increase or a yaw beyond its
        platform's neck; nothing is answered."""
        self._check_open()
        t, yaw = float(t_s), float(yaw_deg)
        if not (math.isfinite(t) and math.isfinite(yaw)):
            raise ValueError(f"head yaw: the point ({t}, {yaw}) is not finite")
        self._session.put(self._key("head/yaw"), json.dumps({"t_s": t, "yaw_deg": yaw}))

    def _server_gone(self) -> bool:
        """Whether the server's liveliness token was withdrawn (reads the watch)."""
        if not self._gone and not self._closed:
            try:
                while True:
                    sample = self._watch.handler.try_recv()
                    if sample is None:
                        break
                    if sample.kind == self._zenoh.SampleKind.DELETE:
                        self._gone = True
            except self._zenoh.ZError:
                pass
        return self._gone

    @property
    def server_gone(self) -> bool:
        """Whether the server has gone (its liveliness token was withdrawn)."""
        return self._server_gone()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    def subscribe(
        self,
        requests: Requests,
        params: Optional[Mapping[str, Any]] = None,
        capacity: int = 64,
    ) -> Subscription:
        """Subscribes to ``requests`` and returns the :class:`Subscription`, whose frames
        start with the server's next block.

        ``requests``: request names (a list, or a comma-separated string), all with the
        AFE parameters ``params``; or ``(name, params)`` pairs, each with its own (over
        ``params``). ``capacity``: blocks kept for a reader that lags; when they are
        all unread, the oldest is dropped for the newest (:attr:`Subscription.lost_messages`
        counts what is lost, here or on the server's side).

        Raises :class:`RemoteError` when the server refuses (an unknown request or
        parameter, an ill-typed value, a limit reached: the most clients it serves or
        subscriptions a client may hold; its message says which), ``ValueError`` for
        parameters that cannot be sent, ``ConnectionError`` when the server does not
        answer.
        """
        from . import _plain_params

        self._check_open()
        capacity = _capacity(capacity)
        specs = [
            {"name": n, "params": _plain_params(p)} for n, p in request_list(requests, params)
        ]
        with self._secret_lock:
            body: Dict[str, Any] = {"client": self.id, "requests": specs}
            if self._secret is not None:
                body["token"] = self._secret
            reply = self._query("subscribe", body)
            if isinstance(reply, dict) and isinstance(reply.get("token"), str):
                self._secret = reply["token"]
        try:
            sub = Subscription(self, reply, capacity)
        except BaseException:
            if isinstance(reply, dict) and isinstance(reply.get("subscription"), int):
                self._unsubscribe(reply["subscription"])
            raise
        return self._track(sub)

    def audio(self, capacity: int = 64) -> Audio:
        """Subscribes to the server's raw audio and returns the :class:`Audio`, an
        iterator of its blocks from the next one on. ``capacity``: blocks kept for a
        reader that lags (the oldest is dropped for the newest, and counted). Give it
        to :func:`afe.stream` to run a local front-end on the server's audio."""
        self._check_open()
        return self._track(Audio(self, _capacity(capacity)))

    def _track(self, receiver: _Self) -> _Self:
        """Registers ``receiver`` to be closed with the connection; returns it."""
        with self._lock:
            self._receivers.add(receiver)
        return receiver

    def _unsubscribe(self, subscription: int, wait: bool = True) -> None:
        """Releases a subscription on the server (quietly: it may have gone); without
        ``wait``, sends the query and returns at once."""
        if self._closed or self._server_gone():
            return
        body = {"client": self.id, "subscription": subscription, "token": self._secret}
        try:
            if wait:
                self._query("unsubscribe", body)
            else:
                self._session.get(self._key("unsubscribe"), payload=json.dumps(body), timeout=self._timeout)
        except (RemoteError, ConnectionError, self._zenoh.ZError):
            pass

    def _check_open(self) -> None:
        if self._closed:
            raise ConnectionError(f"the connection to '{self.name}' is closed")
        if self._server_gone():
            raise ConnectionError(f"the server '{self.name}' has gone")

    def close(self) -> None:
        """Closes every subscription (releasing it on the server) and audio, then the Zenoh
        session. Closing again does nothing."""
        if self._closed:
            return
        with self._lock:
            receivers = list(self._receivers)
        for r in receivers:
            r.close()
        self._closed = True
        for entity in (self._watch, self._token):
            try:
                entity.undeclare()
            except Exception:
                pass
        try:
            self._session.close()
        except Exception:
            pass

    def __enter__(self) -> Remote:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "gone" if self._server_gone() else "connected"
        return (
            f"afe.Remote('{self.name}' at {self.endpoint}, {self.fs_hz:g} Hz, {self.ears} ears, "
            f"{self.block_frames}-frame blocks; {state})"
        )


class _Meta:
    """What a subscription knows of one of its signals."""

    __slots__ = ("key", "shape", "complex", "width", "description", "first_frame", "first_time_s", "fs_hz")

    def __init__(self, d: Mapping[str, Any]) -> None:
        try:
            self.key = str(d["key"])
            self.shape = tuple(int(n) for n in d["frame_shape"])
            self.complex = d.get("dtype") == "complex128"
            self.fs_hz = float(d["fs_hz"])
            self.first_frame = int(d.get("first_frame", 0))
            self.first_time_s = float(d.get("first_time_s", self.first_frame / self.fs_hz))
        except (KeyError, TypeError, ValueError):
            raise RemoteError(f"malformed signal description in the subscription's reply: {d!r}") from None
        self.width = int(np.prod(self.shape, dtype=np.int64)) * (2 if self.complex else 1)
        self.description = dict(d)


def _read_audio(data: bytes, ears: int) -> Tuple[Tuple[int, int, int, int], np.ndarray]:
    """Decodes an audio message of a server with ``ears`` channels (with the Rust
    crate's reader, ``afe_net::wire``): ``(seq, first_frame, frames, t_ns)`` and the
    samples ``[frames, ears]``. Raises :class:`RemoteError` for a message that does not
    follow the wire format."""
    try:
        (seq, first, frames, count, t_ns), samples = _afe.wire_read_audio(data)
    except ValueError as e:
        raise RemoteError(str(e)) from None
    if count != ears:
        raise RemoteError(f"an audio block of {count} channels from a server of {ears}")
    return (seq, first, frames, t_ns), samples.reshape(frames, count)


def _read_frames(data: bytes, metas: List[_Meta]) -> Tuple[Tuple[int, int, int, int], List[Tuple[int, np.ndarray]]]:
    """Decodes a frames message (with the Rust crate's reader, ``afe_net::wire``) of a
    subscription to the signals ``metas``: ``(seq, first_input_frame, input_frames,
    t_ns)`` and, per signal, ``(first_frame, array [rows, *frame_shape])``. Raises
    :class:`RemoteError` for a message that does not follow the wire format or does not
    fit the subscription."""
    try:
        (seq, first_input, n_input, count, t_ns), decoded = _afe.wire_read_frames(data)
    except ValueError as e:
        raise RemoteError(str(e)) from None
    if count != len(metas):
        raise RemoteError(f"{count} signals in a message of a subscription to {len(metas)}")
    parts: List[Tuple[int, np.ndarray]] = []
    for m, (first_frame, rows, width, values) in zip(metas, decoded):
        if width != m.width and rows > 0:
            raise RemoteError(f"{m.key}: {width} values per frame where {m.width} were announced")
        array = values.view(np.complex128) if m.complex else values
        parts.append((first_frame, array.reshape((rows,) + m.shape)))
    return (seq, first_input, n_input, t_ns), parts


class _Receiver(Generic[_Block]):
    """What a subscription to a key of the server has: a bounded queue of its messages
    (a ring that drops its oldest when full: a FIFO that blocks when full would hold up
    the session's reception, and a reader that pauses for long would lose its query
    replies and then its link), the count of messages lost, iteration, and closing."""

    def __init__(self, remote: Remote, key: str, capacity: int) -> None:
        self._remote = remote
        self._closed = False
        self._lost_messages = 0
        self._sub = remote._session.declare_subscriber(key, remote._zenoh.handlers.RingChannel(capacity))

    def _decode(self, data: bytes) -> _Block:
        raise NotImplementedError

    def _release(self, wait: bool) -> None:
        """Tells the server that this receiver has gone, where it needs to know."""

    @property
    def lost_messages(self) -> int:
        """Blocks lost so far: dropped for a reader that lagged (by its queue, or by the
        server for a congested link)."""
        return self._lost_messages

    @property
    def ended(self) -> bool:
        """Whether no more block will come: closed, or the server or the connection has
        gone."""
        return self._closed or self._remote._closed or self._remote._server_gone()

    def recv(self, timeout: Optional[float] = None) -> Optional[_Block]:
        """The next block; waits up to ``timeout`` seconds for it (``None``: until it
        comes). Returns ``None`` when none came in time, and at once when this has
        ended (:attr:`ended` tells which). Raises :class:`RemoteError` for a message that
        does not follow the wire format."""
        deadline = None if timeout is None else time.monotonic() + max(0.0, float(timeout))
        while True:
            sample = self._try_recv()
            if sample is not None:
                return self._decode(sample.payload.to_bytes())
            if self.ended:
                # a block that came just before the server left is still delivered
                sample = None if self._closed else self._try_recv()
                return None if sample is None else self._decode(sample.payload.to_bytes())
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                return None
            time.sleep(_POLL_S if deadline is None else min(_POLL_S, deadline - now))

    def _try_recv(self) -> Any:
        if self._closed:
            return None
        try:
            return self._sub.handler.try_recv()
        except self._remote._zenoh.ZError:
            return None  # the subscriber was undeclared

    def __iter__(self) -> _Receiver[_Block]:
        return self

    def __next__(self) -> _Block:
        block = self.recv()
        if block is None:
            raise StopIteration
        return block

    def close(self) -> None:
        """Stops receiving (and lets the server know). Closing again does nothing."""
        self._close(wait=True)

    def _close(self, wait: bool) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._sub.undeclare()
        except Exception:
            pass
        self._release(wait)

    def __enter__(self: _Self) -> _Self:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        # dropped unclosed: let the server know (quietly; the interpreter may be ending)
        try:
            self._close(wait=False)
        except Exception:
            pass


class Subscription(_Receiver[Frames]):
    """A subscription to requests on an ``afe serve`` server (see
    :meth:`Remote.subscribe`): an iterator of :class:`afe.Frames`, one per block of the
    server's stream, in order; it ends when the server goes or the subscription is
    closed. A context manager: ``with robot.subscribe(...) as sub:`` closes it on
    leaving (and then the server releases it, and its requests' processors go when no
    one else uses them).
    """

    def __init__(self, remote: Remote, reply: Any, capacity: int) -> None:
        if not isinstance(reply, dict):
            raise RemoteError(f"malformed subscription reply: {reply!r}")
        try:
            self.id: int = int(reply["subscription"])
            self.key: str = str(reply["key"])
            self._meta = [_Meta(d) for d in reply["signals"]]
        except (KeyError, TypeError, ValueError):
            raise RemoteError(f"malformed subscription reply: {reply!r}") from None
        self._reply = reply
        # a subscription's messages are numbered from 0: any before the first received
        # were lost too
        self._next_seq = 0
        # from the reply: the index of the first frame the subscription will get, as in Rust
        self._next_frame: List[Optional[int]] = [m.first_frame for m in self._meta]
        self._lost_frames = [0] * len(self._meta)
        super().__init__(remote, self.key, capacity)

    @property
    def reply(self) -> Dict[str, Any]:
        """The server's reply: ``subscription``, ``key``, ``signals`` (each signal's
        description, as :attr:`afe.Signal.meta`), ``fs_hz``, ``ears``, ``block_frames``,
        ``start_frame`` and ``wire_version``."""
        return dict(self._reply)

    @property
    def keys(self) -> List[str]:
        """The output names of the subscription (``ratemap_left``, ...), in order."""
        return [m.key for m in self._meta]

    @property
    def descriptions(self) -> Dict[str, Dict[str, Any]]:
        """Each output's description, by name (as :attr:`afe.Signal.meta`)."""
        return {m.key: dict(m.description) for m in self._meta}

    @property
    def lost_frames(self) -> Dict[str, int]:
        """Frames lost so far per output, from the first the subscription was to get
        (the reply's ``first_frame``)."""
        return {m.key: n for m, n in zip(self._meta, self._lost_frames)}

    def _decode(self, data: bytes) -> Frames:
        """One frames message as :class:`Frames`, counting what was lost before it."""
        (seq, first_input, n_input, t_ns), parts = _read_frames(data, self._meta)
        lost = max(0, seq - self._next_seq)
        self._lost_messages += lost
        self._next_seq = seq + 1
        signals: Dict[str, Signal] = {}
        for i, (m, (first_frame, array)) in enumerate(zip(self._meta, parts)):
            expected = self._next_frame[i]
            if expected is not None:
                self._lost_frames[i] += max(0, first_frame - expected)
            self._next_frame[i] = first_frame + array.shape[0]
            meta = dict(
                m.description,
                first_frame=first_frame,
                first_time_s=m.first_time_s + (first_frame - m.first_frame) / m.fs_hz,
            )
            signals[m.key] = Signal(array, meta)
        return Frames(seq, first_input, n_input, t_ns, lost, signals)

    def _release(self, wait: bool) -> None:
        self._remote._unsubscribe(self.id, wait)

    def __repr__(self) -> str:
        state = "ended" if self.ended else "active"
        return (
            f"afe.Subscription({self.id} on '{self._remote.name}': {', '.join(self.keys)}; "
            f"{self._lost_messages} lost; {state})"
        )


class AudioBlock:
    """One block of a server's raw audio, as its port had it.

    Attributes:
        seq: the block's message number on the server's audio key.
        first_frame: index on the server's port of the block's first frame.
        samples: the samples, ``[frames, ears]`` float64, the server's bit for bit.
        t_ns: Unix time in ns at which the block's last frame was due on the port.
        lost_messages: blocks lost just before this one.
        lost_frames: frames lost just before this block (a gap on the port's index).
    """

    __slots__ = ("seq", "first_frame", "samples", "t_ns", "lost_messages", "lost_frames")

    def __init__(
        self, seq: int, first_frame: int, samples: np.ndarray, t_ns: int, lost_messages: int, lost_frames: int
    ) -> None:
        self.seq = int(seq)
        self.first_frame = int(first_frame)
        self.samples = samples
        self.t_ns = int(t_ns)
        self.lost_messages = int(lost_messages)
        self.lost_frames = int(lost_frames)

    def __repr__(self) -> str:
        return f"afe.AudioBlock({self.seq}: frames {self.first_frame}.. x{self.samples.shape[0]}, {self.lost_frames} lost before)"


class Audio(_Receiver[AudioBlock]):
    """The raw audio a server publishes (see :meth:`Remote.audio`): an iterator of
    :class:`AudioBlock`, from the server's next block on, in order. Give it to
    :func:`afe.stream` to run a local front-end on the server's audio. Losses are
    counted from the first block received; it ends when the server goes or it is
    closed. A context manager."""

    def __init__(self, remote: Remote, capacity: int) -> None:
        self.fs_hz: float = remote.fs_hz
        self.ears: int = remote.ears
        self.block_frames: int = remote.block_frames
        self._next_seq: Optional[int] = None
        self._next_frame: Optional[int] = None
        self._lost_frames = 0
        super().__init__(remote, remote._key("audio"), capacity)

    @property
    def lost_frames(self) -> int:
        """Frames lost so far, after the first block received."""
        return self._lost_frames

    def _decode(self, data: bytes) -> AudioBlock:
        (seq, first, _frames, t_ns), samples = _read_audio(data, self.ears)
        messages = 0 if self._next_seq is None else max(0, seq - self._next_seq)
        frames = 0 if self._next_frame is None else max(0, first - self._next_frame)
        self._lost_messages += messages
        self._lost_frames += frames
        self._next_seq, self._next_frame = seq + 1, first + samples.shape[0]
        return AudioBlock(seq, first, samples, t_ns, messages, frames)

    def __repr__(self) -> str:
        state = "ended" if self.ended else "active"
        return (
            f"afe.Audio('{self._remote.name}': {self.fs_hz:g} Hz, {self.ears} ears; "
            f"{self._lost_frames} frames lost; {state})"
        )
