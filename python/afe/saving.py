"""Saving signals with their descriptions: :func:`afe.save` writes an ``.npz`` in the
layout of ``afe extract -o out.npz`` (one array per output, named by its key, and the
descriptions as JSON text in the entry ``afe_metadata``), or to a path ending in
``.zarr`` a Zarr v3 group in the layout of one file of an ``afe batch`` store (one array
per output, its description in the array's ``afe`` attribute); :func:`afe.load` reads
either back into :class:`afe.Signal` objects.

>>> import afe, numpy as np, os, tempfile
>>> out = afe.process(np.zeros((1600, 2)), 16000, ["ild"])
>>> path = os.path.join(tempfile.mkdtemp(), "cues.npz")
>>> afe.save(path, out)
>>> back = afe.load(path)
>>> back["ild_mono"].hop_s, np.array_equal(back["ild_mono"], out["ild_mono"])
(0.01, True)
"""

from __future__ import annotations

import json
import os
import stat
from typing import Any, Dict, Mapping, Union

import numpy as np

from . import _afe
from .signal import Signal

#: The ``.npz`` entry holding every array's description (``afe::npy::METADATA_ENTRY``).
METADATA_ENTRY = "afe_metadata"

PathLike = Union[str, "os.PathLike[str]"]


def save(path: PathLike, signals: Union[Signal, Mapping[str, Signal]]) -> None:
    """Writes ``signals`` to the ``.npz`` file ``path`` (replaced if it exists) as
    ``afe extract`` writes its output: each array under its name, float64 or complex128
    as computed, uncompressed, and every signal's description (:attr:`afe.Signal.meta`)
    as JSON text in the entry ``afe_metadata``, which ``numpy.load`` reads without
    pickling (``json.loads(str(np.load(path)["afe_metadata"]))``).

    A ``path`` ending in ``.zarr`` is written as a Zarr v3 group instead (any Zarr v3
    reader opens it: ``zarr.open_group(path)[name].attrs["afe"]`` is a description). It
    replaces a group ``afe.save`` wrote before, and refuses any other existing path.
    Arrays are float64, float32, complex128 or complex64, of at least one axis; the
    description's ``dtype`` is set to the array's.

    ``signals``: ``{name: Signal}`` (``afe.process``'s output, ``afe.load``'s, a block of
    ``afe.stream``, ``store[file_id]``) or one :class:`afe.Signal` (saved under its key).
    Raises ``ValueError`` for a value that is not an :class:`afe.Signal` (a plain array
    has no description to save: ``np.savez`` is for those) or for the reserved name
    ``afe_metadata``.
    """
    if isinstance(signals, Signal):
        signals = {signals.key: signals}
    if not isinstance(signals, Mapping):
        raise ValueError(
            f"signals must be a dict of names to afe.Signal (or one afe.Signal), got "
            f"{type(signals).__name__}"
        )
    arrays: Dict[str, np.ndarray] = {}
    meta: Dict[str, Any] = {}
    zarr = os.fspath(path).rstrip("/\\").endswith(".zarr")
    for name, s in signals.items():
        if name == METADATA_ENTRY:
            raise ValueError(f"'{METADATA_ENTRY}' is the entry of the descriptions: name the signal otherwise")
        if not isinstance(s, Signal):
            raise ValueError(
                f"signals[{name!r}] is a {type(s).__name__}, not an afe.Signal: it has no "
                "description to save (np.savez saves plain arrays)"
            )
        arrays[str(name)] = np.ascontiguousarray(np.asarray(s).view(np.ndarray))
        meta[str(name)] = s.meta
    if zarr:
        # native byte order: the group stores the values as this machine holds them
        native = {k: a.astype(a.dtype.newbyteorder("="), copy=False) for k, a in arrays.items()}
        items = [
            (k, a.dtype.name, list(a.shape), a.tobytes(), meta[k])
            for k, a in native.items()
        ]
        _afe.save_zarr(os.fspath(path), items)
        return
    arrays[METADATA_ENTRY] = np.array(json.dumps(meta))
    # through a file object: np.savez would append ".npz" to a path without it
    with open(os.fspath(path), "wb") as f:
        # numpy's stub has savez(file, *args: ArrayLike, allow_pickle: bool, **kwds: ArrayLike):
        # mypy matches a **dict's values to the keyword-only allow_pickle too (passing the
        # flag here instead would save an array "allow_pickle" with the older numpy whose
        # savez has no such flag, which pyproject.toml's numpy>=1.21 admits)
        np.savez(f, **arrays)  # type: ignore[arg-type]


def _npz_meta(z: Any, path: str) -> Dict[str, Dict[str, Any]]:
    """The descriptions of the open afe ``.npz`` ``z``, one per array, in the file's order."""
    if METADATA_ENTRY not in z.files:
        raise ValueError(
            f"'{path}' has no '{METADATA_ENTRY}' entry: not written by afe (np.load reads "
            "its arrays)"
        )
    meta = json.loads(str(z[METADATA_ENTRY]))
    names = [k for k in z.files if k != METADATA_ENTRY]
    missing = [k for k in names if k not in meta]
    if missing:
        raise ValueError(f"'{path}': no description of {', '.join(missing)} in '{METADATA_ENTRY}'")
    return {k: meta[k] for k in names}


def read_npz(path: PathLike) -> "tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]":
    """The arrays of an afe ``.npz`` (in the file's order) and their descriptions."""
    path = os.fspath(path)
    with np.load(path, allow_pickle=False) as z:
        meta = _npz_meta(z, path)
        arrays = {k: z[k] for k in meta}
    return arrays, meta


def read_zarr(path: PathLike) -> "tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]":
    """The arrays of a Zarr group written by :func:`afe.save` (in their saved order) and
    their descriptions."""
    arrays, infos = _afe.load_zarr(os.fspath(path))
    return dict(arrays), dict(infos)


def read_descriptions(path: PathLike) -> Dict[str, Dict[str, Any]]:
    """The descriptions of an afe ``.npz`` or of a Zarr group written by :func:`afe.save`,
    in the saved order, without reading the arrays (from the ``.npz``'s metadata entry, or
    from the ``zarr.json`` of the group and of each array)."""
    path = os.fspath(path)
    if not os.path.isdir(path):
        with np.load(path, allow_pickle=False) as z:
            return _npz_meta(z, path)
    order = zarr_attributes(path)["afe_saved"]["order"]
    return {k: zarr_attributes(os.path.join(path, k))["afe"] for k in order}


def zarr_attributes(folder: PathLike) -> Dict[str, Any]:
    """The attributes in the ``zarr.json`` of the Zarr node ``folder`` (``{}`` if none);
    ``OSError`` or ``ValueError`` where it cannot be read (a FIFO or a device in its place
    is refused without blocking on it)."""
    path = os.path.join(os.fspath(folder), "zarr.json")
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise ValueError(f"'{path}' is not a regular file (a FIFO or a device)")
    with open(path, encoding="utf-8") as f:
        node = json.load(f)
    return (node.get("attributes") if isinstance(node, dict) else None) or {}


def load(path: PathLike) -> Dict[str, Signal]:
    """Reads an ``.npz`` written by :func:`afe.save`, ``afe extract -o out.npz`` or
    ``afe batch --format npz``, or a Zarr group written by :func:`afe.save`, back into
    ``{name: Signal}``, each with its description, in the saved order. Raises
    ``FileNotFoundError`` for a missing path and ``ValueError`` for an ``.npz`` without
    afe's descriptions or a folder that is not such a group (a batch store opens with
    :func:`afe.open_store`).

    A Zarr group is read within the bounds its metadata declares, checked against its
    files before any value is read: a chunk missing, cut short, or not a regular file (a
    FIFO) raises ``ValueError`` naming the array and chunk; values that would not fit the
    memory available raise ``MemoryError``. Ctrl-C stops the read (``KeyboardInterrupt``)."""
    if not os.path.exists(os.fspath(path)):
        raise FileNotFoundError(f"no file or folder '{os.fspath(path)}'")
    reader = read_zarr if os.path.isdir(os.fspath(path)) else read_npz
    arrays, meta = reader(path)
    return {k: Signal(v, meta[k]) for k, v in arrays.items()}
