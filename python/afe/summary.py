"""Parameter summaries: what each processor of a graph runs with, as ``afe list REQUEST``
shows a chain, but with only the values that differ from the AFE's defaults (the AFE's
``getParameterSummary``, made readable).

>>> import afe, numpy as np
>>> x = np.zeros((1600, 2))
>>> out = afe.process(x, 16000, [("ratemap", {"rm_wSizeSec": 0.05}), "ild"])
>>> print(afe.summary(out))
ratemap -> ratemap_left, ratemap_right
    ratemap
        rm_wSizeSec              0.05 s
    innerhaircell
    filterbank
    time
ild -> ild_mono
    ild
    innerhaircell                (shared with ratemap)
"""

from __future__ import annotations

import json
from typing import Any, Dict, List, Mapping, Optional, Tuple

#: Values of a vector shown before the ``...`` and its last one.
HEAD = 3


def _number(v: Any) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return json.dumps(v) if not isinstance(v, str) else repr(v)
    return f"{v:.6g}"


def value_text(v: Any) -> str:
    """A parameter value for reading: numbers in 6 significant digits, strings quoted,
    vectors longer than ``HEAD + 2`` abbreviated to their first values, ``...``, the
    last, and their length (``[80, 95.4, 112.7, ..., 8000] (32 values)``)."""
    if isinstance(v, (list, tuple)):
        items = [_number(e) for e in v]
        if len(items) > HEAD + 2:
            return f"[{', '.join(items[:HEAD])}, ..., {items[-1]}] ({len(items)} values)"
        return f"[{', '.join(items)}]"
    return _number(v)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b or a == b
    return a == b


class _Catalog:
    """Each processor's declared parameters with their defaults and units."""

    def __init__(self, entries: List[Dict[str, Any]]) -> None:
        self.params: Dict[str, List[Dict[str, Any]]] = {e["name"]: e["parameters"] for e in entries}
        self.chains: Dict[str, List[str]] = {e["name"]: e["chain"] for e in entries}
        self._defaults: Dict[Tuple[str, Optional[float]], Dict[str, Any]] = {}

    def changed(
        self, processor: str, values: Mapping[str, Any], defaults: Mapping[str, Any]
    ) -> List[Tuple[str, Any, str]]:
        """``(name, value, unit)`` of the parameters of ``processor`` whose value in
        ``values`` differs from the one in ``defaults`` (the request's effective
        parameters at its defaults, derived ones such as ``fb_cfHz`` included), or from
        the catalogue's default where ``defaults`` lacks it."""
        out = []
        for p in self.params.get(processor, []):
            if p["name"] not in values:
                continue
            v, d = values[p["name"]], defaults.get(p["name"], p["default"])
            if d is None and v in (None, [], ""):
                continue
            if d is None or not _same(v, d):
                out.append((p["name"], v, p["unit"]))
        return out

    def defaults(self, request: str, fs_hz: Optional[float]) -> Dict[str, Any]:
        """The effective parameters of ``request`` placed with no parameter at ``fs_hz``
        (derived values such as the default ``fb_nChannels`` and ``fb_cfHz`` depend on
        nothing else); empty where that cannot be placed (a default grid above Nyquist)."""
        key = (request, fs_hz)
        if key not in self._defaults:
            from . import Manager

            found: Dict[str, Any] = {}
            if fs_hz:
                try:
                    m = Manager(fs_hz, 2)
                    found = m.request_parameters(m.add_request(request))
                except (ValueError, KeyError):
                    pass
            self._defaults[key] = found
        return self._defaults[key]

    def own(self, chain: List[str], values: Mapping[str, Any]) -> Tuple[Tuple[str, str], ...]:
        """What makes a processor the one it is: its chain's processors' parameters (two
        requests share a processor when its whole chain has equal parameters)."""
        names = [p["name"] for n in chain for p in self.params.get(n, [])]
        return tuple((n, json.dumps(values.get(n), sort_keys=True)) for n in names)


def _entries_of_signals(signals: Mapping[str, Any]) -> List[Dict[str, Any]]:
    """One entry per request instance: the signals' keys grouped by ``<name>[_k]``."""
    groups: Dict[str, Dict[str, Any]] = {}
    for key, s in signals.items():
        if hasattr(s, "meta"):
            meta = s.meta
        elif isinstance(s, Mapping):
            meta = dict(s)
        else:
            raise ValueError(
                f"summary of signals: [{key!r}] is a {type(s).__name__}, not an afe.Signal "
                "(or its meta dict): a plain array has no description of its processors; "
                "give afe.process's output, afe.load's, or an afe.Manager"
            )
        label = key.rsplit("_", 1)[0] if meta.get("ear") and key.endswith("_" + meta["ear"]) else key
        chain = list(meta.get("processors", []))
        g = groups.setdefault(
            label, {"label": label, "outputs": [], "chain": chain, "request": chain[0] if chain else label,
                    "fs_hz": meta.get("audio_fs_hz"), "parameters": dict(meta.get("parameters", {}))}
        )
        g["outputs"].append(key)
    return list(groups.values())


def _entries_of_manager(m: Any) -> List[Dict[str, Any]]:
    from . import _catalog

    chains = {e["name"]: e["chain"] for e in _catalog()}
    out = []
    for h, name in m._names.items():
        keys = m.request_outputs(h)
        label = keys[0].rsplit("_", 1)[0] if keys else name
        out.append({"label": label, "outputs": keys, "chain": list(chains.get(name, [name])),
                    "request": name, "fs_hz": m.fs, "parameters": m.request_parameters(h)})
    return out


def _covered(entry: Dict[str, Any], others: List[Dict[str, Any]], catalog: _Catalog) -> bool:
    """Whether ``entry`` (an intermediate signal kept with ``keep="all"``) is the tail of
    another entry's chain, with the same parameters."""
    n = len(entry["chain"])
    mine = catalog.own(entry["chain"], entry["parameters"])
    return any(
        o is not entry and len(o["chain"]) > n and o["chain"][-n:] == entry["chain"]
        and catalog.own(o["chain"][-n:], o["parameters"]) == mine
        for o in others
    )


def summary(source: Any) -> str:
    """A readable summary of the processors a graph runs and their parameters: for each
    request (instance), its outputs and its chain of processors from the request down to
    ``time``, each with the parameters whose value is not the AFE's default (vectors
    abbreviated: first values, ``...``, the last, and the length). A processor shared with
    an earlier request is named once, with the request it is shared with.

    ``source``: an :class:`afe.Manager`, or signals (``afe.process``'s output, a block of
    :func:`afe.stream`, :func:`afe.load`'s output, ``store[file_id]``): a mapping of
    output names to :class:`afe.Signal` (or to their ``meta`` dicts).
    """
    from . import Manager, _catalog

    catalog = _Catalog(_catalog())
    if isinstance(source, Manager):
        entries = _entries_of_manager(source)
    elif isinstance(source, Mapping) or hasattr(source, "items"):
        entries = _entries_of_signals(dict(source.items()))
    else:
        raise ValueError(
            f"summary of a {type(source).__name__}: give an afe.Manager or signals "
            "({name: afe.Signal}, as afe.process returns them)"
        )
    entries = [e for e in entries if not _covered(e, entries, catalog)]
    lines: List[str] = []
    seen: Dict[Tuple[str, Tuple[Tuple[str, str], ...]], str] = {}
    for e in entries:
        lines.append(f"{e['label']} -> {', '.join(e['outputs'])}")
        chain = e["chain"]
        for i, proc in enumerate(chain):
            ident = (proc, catalog.own(chain[i:], e["parameters"]))
            if ident in seen:
                lines.append(f"    {proc:<28} (shared with {seen[ident]})")
                break
            seen[ident] = e["label"]
            lines.append(f"    {proc}")
            defaults = catalog.defaults(e["request"], e["fs_hz"])
            for name, v, unit in catalog.changed(proc, e["parameters"], defaults):
                lines.append(f"        {name:<24} {value_text(v)}{' ' + unit if unit else ''}")
    return "\n".join(lines)


def manager_text(m: Any, head: str) -> str:
    """``repr`` of a manager: ``head`` and its summary."""
    n = len(m._names)
    body = summary(m) if n else ""
    return f"{head}: {n} request{'s' if n != 1 else ''}" + (f"\n{body}" if body else "")

