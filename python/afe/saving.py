"""Saving signals with their descriptions: :func:`afe.save` writes an ``.npz`` in the
layout of ``afe extract -o out.npz`` (one array per output, named by its key, and the
descriptions as JSON text in the entry ``afe_metadata``); :func:`afe.load` reads such a
file, whoever wrote it, back into :class:`afe.Signal` objects.

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
from typing import Any, Dict, Mapping, Union

import numpy as np

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
    arrays[METADATA_ENTRY] = np.array(json.dumps(meta))
    # through a file object: np.savez would append ".npz" to a path without it
    with open(os.fspath(path), "wb") as f:
        np.savez(f, **arrays)


def read_npz(path: PathLike) -> "tuple[Dict[str, np.ndarray], Dict[str, Dict[str, Any]]]":
    """The arrays of an afe ``.npz`` (in the file's order) and their descriptions."""
    path = os.fspath(path)
    with np.load(path, allow_pickle=False) as z:
        if METADATA_ENTRY not in z.files:
            raise ValueError(
                f"'{path}' has no '{METADATA_ENTRY}' entry: not written by afe (np.load reads "
                "its arrays)"
            )
        meta = json.loads(str(z[METADATA_ENTRY]))
        arrays = {k: z[k] for k in z.files if k != METADATA_ENTRY}
    missing = [k for k in arrays if k not in meta]
    if missing:
        raise ValueError(f"'{path}': no description of {', '.join(missing)} in '{METADATA_ENTRY}'")
    return arrays, meta


def load(path: PathLike) -> Dict[str, Signal]:
    """Reads an ``.npz`` written by :func:`afe.save`, ``afe extract -o out.npz`` or
    ``afe batch --format npz`` back into ``{name: Signal}``, each with its description,
    in the file's order. Raises ``FileNotFoundError`` for a missing file and
    ``ValueError`` for an ``.npz`` without afe's descriptions."""
    arrays, meta = read_npz(path)
    return {k: Signal(v, meta[k]) for k, v in arrays.items()}
