"""Corpus extraction: the same requests over many WAV files into one store.

``afe.batch`` runs the Rust engine over every core, or distributes files over any
``concurrent.futures.Executor`` (a Dask cluster's ``client.get_executor()`` spreads a
corpus over machines into one store). ``afe.open_store`` reads a store back as numpy.
A store resumes: files already recorded as done are never computed again.
"""

from __future__ import annotations

import json
import os
import sys
import time
from concurrent.futures import Executor, as_completed
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _afe
from .signal import Signal, signals

PathLike = Union[str, "os.PathLike[str]"]


def _paths(inputs: Union[PathLike, Sequence[PathLike]]) -> List[str]:
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    paths = [os.fspath(p) for p in inputs]
    if not paths:
        raise ValueError("no input given: pass folders, glob patterns, WAV files or manifests")
    return paths


def _requests(requests: Union[str, Sequence[str]]) -> List[str]:
    names = requests.split(",") if isinstance(requests, str) else list(requests)
    names = [str(n).strip() for n in names if str(n).strip()]
    if not names:
        raise ValueError("no request given, e.g. requests=['ratemap', 'ild']")
    return names


def _compute_one(store: str, file_id: str, path: str, audio_s: float) -> Dict[str, Any]:
    """One file on an executor's worker (imports afe there); returns its record."""
    return _afe.batch_compute(store, file_id, path, audio_s)


def batch(
    inputs: Union[PathLike, Sequence[PathLike]],
    requests: Union[str, Sequence[str]],
    params: Optional[Mapping[str, Any]] = None,
    out: Optional[PathLike] = None,
    executor: Optional[Executor] = None,
    *,
    jobs: Optional[int] = None,
    shard: Optional[Tuple[int, int]] = None,
    on_error: str = "skip",
    progress: Optional[str] = None,
    format: str = "zarr",
    dtype: str = "float64",
    overwrite: bool = False,
) -> Dict[str, Any]:
    """Computes ``requests`` for every WAV file of ``inputs`` into the store ``out``.

    ``inputs``: folders (searched for ``.wav`` files), glob patterns, WAV files or
    manifests (one ``id<TAB>path`` per line); a file's id is its path relative to its
    input. ``params``: AFE parameters shared by the requests. ``out``: the store folder
    (Zarr v3, one group per file id and one array per output; ``format="npz"`` writes one
    ``.npz`` per file as ``afe extract`` does). ``dtype="float32"`` stores the values
    (computed in float64) rounded to float32 (complex64 for spectra): half the disk, as
    ``afe batch --dtype f32`` writes them; a store keeps one type.

    ``executor=None`` runs the Rust engine with ``jobs`` files at once (default: one per
    core). Any ``concurrent.futures.Executor`` computes the files as its tasks instead,
    e.g. ``dask.distributed.Client(...).get_executor()`` (workers need ``afe`` installed
    and the inputs and store on a shared file system).

    Files the store records as done and holds whole on disk are skipped, so a run that
    was killed resumes where it stopped (a file whose group, array or chunk was deleted or
    cut short is computed again). Runs sharing a store (two calls at once, shards,
    executor tasks) share its files: each file is claimed while it is written, and one
    done by another run is not computed again. A store that cannot be written (a full
    disk) raises ``OSError``, the files not written left to the next run; so does
    ``overwrite`` while another run writes the store. ``shard=(i, n)`` computes only shard ``i`` of ``n`` (by a stable hash of
    the ids), for independent jobs filling one store. A file that fails is recorded and
    skipped, or with ``on_error="stop"`` stops the run (``RuntimeError``) after the files
    in flight. ``progress``: ``"bar"`` (stderr), ``"jsonl"`` (one JSON line per file on
    stdout) or ``"none"``; default: a bar on a terminal, else none. A store made with
    other requests, parameters or ``dtype`` is refused (``ValueError``) unless
    ``overwrite``.

    Returns the summary: ``files``, ``already_done``, ``done``, ``done_elsewhere`` (by
    another run sharing the store meanwhile), ``failed`` (a list of ``{"id", "error"}``),
    ``not_started``, ``audio_s``, ``wall_s``, ``x_real_time``; the Rust engine's also
    ``incomplete`` (files recorded as done but found incomplete on disk, computed again)
    and ``warnings`` (log lines that could not be read).
    """
    from . import _plain_params

    if out is None:
        raise ValueError("give the store folder: out='features.zarr'")
    if progress is None:
        progress = "bar" if sys.stderr.isatty() else "none"
    if on_error not in ("skip", "stop"):
        raise ValueError(f"on_error must be 'skip' or 'stop', got {on_error!r}")
    if progress not in ("bar", "jsonl", "none"):
        raise ValueError(f"progress must be 'bar', 'jsonl' or 'none', got {progress!r}")
    if shard is not None:
        i, n = (int(v) for v in shard)
        shard = (i, n)
    if jobs is not None and int(jobs) < 1:
        raise ValueError(f"jobs must be 1 or more, got {jobs}")
    spec = {
        "requests": _requests(requests),
        "params": _plain_params(params),
        "format": format,
        "dtype": str(dtype),
    }
    options = {
        "jobs": int(jobs or 0),
        "shard": list(shard) if shard is not None else None,
        "on_error": on_error,
        "progress": progress,
        "overwrite": bool(overwrite),
    }
    paths, store = _paths(inputs), os.path.abspath(os.fspath(out))
    if executor is None:
        return _afe.batch_run(paths, store, spec, options)
    return _distribute(executor, paths, store, spec, options, on_error, progress)


def _distribute(
    executor: Executor,
    paths: List[str],
    store: str,
    spec: Dict[str, Any],
    options: Dict[str, Any],
    on_error: str,
    progress: str,
) -> Dict[str, Any]:
    start = time.monotonic()
    files, already = _afe.batch_plan(paths, store, spec, options)
    summary: Dict[str, Any] = {
        "files": len(files) + already,
        "already_done": already,
        "done": 0,
        "done_elsewhere": 0,
        "failed": [],
        "not_started": 0,
        "audio_s": 0.0,
    }
    total_s = sum(f[2] for f in files)
    # longest first: tasks are submitted in the plan's order
    futures = [
        executor.submit(_compute_one, store, fid, os.path.abspath(path), audio_s)
        for fid, path, audio_s in files
    ]
    stopped = False
    # as_completed waits on each future once (a wait() per completion over all pending
    # futures costs O(n^2) and took a core from the workers on large corpora)
    for fut in as_completed(futures):
        if fut.cancelled():
            continue
        record = fut.result()
        if record.get("elsewhere"):
            summary["done_elsewhere"] += 1
        elif record["status"] == "done":
            summary["done"] += 1
            summary["audio_s"] += record["audio_s"]
        else:
            summary["failed"].append({"id": record["id"], "error": record["error"]})
            if on_error == "stop" and not stopped:
                stopped = True
                for f in futures:
                    f.cancel()
        _show(progress, record, summary, len(files), total_s, time.monotonic() - start)
    summary["wall_s"] = time.monotonic() - start
    summary["not_started"] = len(files) - summary["done"] - summary["done_elsewhere"] - len(summary["failed"])
    summary["x_real_time"] = summary["audio_s"] / summary["wall_s"] if summary["wall_s"] > 0 else 0.0
    summary["failed"].sort(key=lambda f: f["id"])
    if progress == "bar":
        sys.stderr.write("\n")
    if progress == "jsonl":
        print(json.dumps(dict(summary, event="summary")), flush=True)
    if stopped:
        first = summary["failed"][0]
        raise RuntimeError(f"stopped at '{first['id']}': {first['error']}")
    return summary


def _show(progress: str, record: Dict[str, Any], summary: Dict[str, Any], files: int, total_s: float, elapsed: float) -> None:
    count = summary["done"] + summary["done_elsewhere"] + len(summary["failed"])
    speed = summary["audio_s"] / elapsed if elapsed > 0 else 0.0
    if progress == "jsonl":
        event = dict(record, event="file", done=summary["done"], failed=len(summary["failed"]), files=files, x_real_time=speed)
        print(json.dumps(event), flush=True)
    elif progress == "bar":
        sys.stderr.write(
            f"\r{count}/{files} files ({len(summary['failed'])} failed) · "
            f"{summary['audio_s'] / 3600:.2f} of {total_s / 3600:.2f} h audio · {speed:.0f}x real time"
        )
        sys.stderr.flush()


class Store:
    """A batch store read back: its requests and parameters, the files it holds, and
    each file's arrays as numpy (``store[file_id]`` → ``{name: array}``)."""

    def __init__(self, path: PathLike):
        self.path = os.fspath(path)
        if os.path.isfile(self.path) and self.path.endswith(".npz"):
            self._open_saved("npz-file", ".npz")
            return
        if _is_saved_group(self.path):
            self._open_saved("zarr-group", ".zarr")
            return
        status = _afe.store_status(self.path)
        self.format: str = status["format"]
        self.requests: List[str] = status["requests"]
        self.params: Dict[str, Any] = status["params"]
        self.param_hash: str = status["param_hash"]
        #: how the values are stored: ``"float64"`` or ``"float32"``
        self.dtype: str = status["dtype"]
        latest = status["files"]
        #: file id → record of the files done (path, audio_s, compute_s, time), each
        #: checked on disk (its metadata and its chunks' sizes)
        self.done: Dict[str, Dict[str, Any]] = {r["id"]: r for r in latest if r["status"] == "done"}
        #: file id → error of the files that failed
        self.failed: Dict[str, str] = {r["id"]: r["error"] for r in latest if r["status"] == "failed"}
        #: file id → what is wrong, for files recorded as done whose output is missing or
        #: cut short on disk (the next ``afe.batch`` into the store computes them again)
        self.missing: Dict[str, str] = {r["id"]: r["error"] for r in latest if r["status"] == "missing"}
        #: lines of the store's logs that could not be read, skipped
        self.warnings: List[str] = status["warnings"]

    def _open_saved(self, format: str, suffix: str) -> None:
        """One ``.npz`` (``afe extract``'s or :func:`afe.save`'s) or one Zarr group of
        :func:`afe.save` as a read-only store of one file, whose id is the path's last
        name without its suffix."""
        from .saving import read_descriptions

        meta = read_descriptions(self.path)
        self.format = format
        requests: List[str] = []
        for m in meta.values():
            chain = m.get("processors") or [m.get("name", "")]
            if chain[0] not in requests:
                requests.append(chain[0])
        self.requests = requests
        self.params = {}
        self.param_hash = ""
        narrow = any(m.get("dtype") in ("float32", "complex64") for m in meta.values())
        self.dtype = "float32" if narrow else "float64"
        name = os.path.basename(self.path.rstrip("/"))
        file_id = name[: -len(suffix)] if name.endswith(suffix) else name
        record = {"id": file_id, "path": self.path, "status": "done"}
        # a Zarr group is checked on disk as afe.load reads it (each chunk present, of its size)
        damage = _afe.check_zarr(self.path) if format == "zarr-group" else None
        self.done = {} if damage else {file_id: record}
        self.failed = {}
        self.missing = {file_id: damage} if damage else {}
        self.warnings = []

    def _read_saved(self) -> Tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]:
        from .saving import read_npz, read_zarr

        return read_zarr(self.path) if os.path.isdir(self.path) else read_npz(self.path)

    def ids(self) -> List[str]:
        """The ids of the files done, sorted."""
        return sorted(self.done)

    def __len__(self) -> int:
        return len(self.done)

    def __iter__(self) -> Iterator[str]:
        return iter(self.ids())

    def __contains__(self, file_id: object) -> bool:
        return file_id in self.done

    def __getitem__(self, file_id: str) -> Dict[str, Signal]:
        """File ``file_id``'s outputs, each an :class:`afe.Signal` with its description."""
        arrays, meta = self._read(file_id)
        return signals(arrays, meta)

    def info(self, file_id: str) -> Dict[str, Dict[str, Any]]:
        """Each array's description (kind, axes, rates in Hz, centre frequencies, lags,
        window and hop, parameters: :attr:`afe.Signal.meta`)."""
        return self._read(file_id)[1]

    def _read(self, file_id: str) -> Tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]:
        if file_id not in self.done:
            why = ""
            if file_id in self.failed:
                why = f" (it failed: {self.failed[file_id]})"
            elif file_id in self.missing and self.format == "zarr-group":
                why = f" ({self.missing[file_id]})"
            elif file_id in self.missing:
                why = (
                    f" (recorded as done, but {self.missing[file_id]}: "
                    "run the batch again to compute it)"
                )
            raise KeyError(f"the store holds no file '{file_id}'{why}")
        if self.format in ("npz-file", "zarr-group"):
            return self._read_saved()
        if self.format == "npz":
            with np.load(os.path.join(self.path, file_id + ".npz")) as z:
                meta = json.loads(str(z["afe_metadata"]))
                return {k: z[k] for k in z.files if k != "afe_metadata"}, meta
        arrays, infos = _afe.store_read(self.path, file_id)
        return arrays, dict(infos)

    def __repr__(self) -> str:
        return (
            f"afe.Store({self.path!r}: {self.format}, {','.join(self.requests)}, "
            f"{len(self.done)} done, {len(self.failed)} failed, {len(self.missing)} missing)"
        )


def _is_saved_group(path: str) -> bool:
    """Whether ``path`` is a Zarr group written by :func:`afe.save`."""
    from .saving import zarr_attributes

    try:
        return "afe_saved" in zarr_attributes(path)
    except (OSError, ValueError):
        return False


def open_store(path: PathLike) -> Store:
    """Opens a store written by ``afe.batch`` or ``afe batch`` (``ValueError`` if the
    folder is not one), or a single ``.npz`` of ``afe extract`` or :func:`afe.save`, or a
    Zarr group of :func:`afe.save`, as a read-only store of one file (``format``
    ``"npz-file"`` or ``"zarr-group"``, its id the path's name without ``.npz`` or
    ``.zarr``, ``requests`` from its signals' descriptions, ``params`` empty: each
    signal's :attr:`afe.Signal.parameters` has its own)."""
    return Store(path)
