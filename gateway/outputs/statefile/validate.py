"""The state file is untrusted input: every field of its header is checked here, before
anything of it is used (a damaged disk, a hand-edited file or a crafted one).

:func:`check_header` raises :class:`ValueError` naming the first field that is wrong and
why; the caller sets the file aside and the gateway starts empty. Checked: types (a number
is an ``int``/``float``, never a string or a boolean), ranges (a sequence number below
2**53, so that it and what a restart adds to it fit the registers' and the store's
integers; a save time a Unix time between 1970 and 5138; finite sample times), sizes
(texts, lists) and the assessment of every loop, field by field, as
:class:`stiction.Assessment` has them (a field added to it later, and not checked here yet,
may hold plain values only). Anything else is refused.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from stiction import Assessment, Verdict

__all__ = ["MAX_SEQ", "MAX_WALL", "check_header"]

MAX_SEQ = 2**53
"""Sequence numbers saved are below this (int64 arithmetic after a restart's bump)."""
MAX_WALL = 1e11
"""Save and assessment times are Unix times in 0 .. 1e11 (year 5138)."""
MAX_TEXT = 10_000  # characters of a reason, a warning, a note
MAX_ITEMS = 1_000  # warnings or evidence of one assessment
MAX_WINDOW = 2**31  # samples of one window
_NUMBERS = ("period_s", "stiction_index", "fd", "fs", "jump", "fd_op", "fs_op", "confidence")
_VERDICTS = frozenset(str(v) for v in Verdict)
_FIELDS = frozenset(f.name for f in dataclasses.fields(Assessment))


def _number(x: Any, where: str, lo: float = -math.inf, hi: float = math.inf, *,
            finite: bool = True) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{where}: {type(x).__name__} where a number belongs")
    v = float(x)
    if finite and not math.isfinite(v):
        raise ValueError(f"{where}: {v} is not finite")
    if not lo <= v <= hi and not math.isnan(v):
        raise ValueError(f"{where}: {v:g} is outside {lo:g} .. {hi:g}")
    return v


def _integer(x: Any, where: str, lo: int, hi: int) -> int:
    if isinstance(x, bool) or not isinstance(x, int):
        raise ValueError(f"{where}: {type(x).__name__} where an integer belongs")
    if not lo <= x <= hi:
        shown = str(x) if abs(x) < 10**18 else f"a number of {x.bit_length()} bits"
        raise ValueError(f"{where}: {shown} is outside {lo} .. {hi}")
    return x


def _text(x: Any, where: str, limit: int = MAX_TEXT) -> str:
    if not isinstance(x, str):
        raise ValueError(f"{where}: {type(x).__name__} where a text belongs")
    if len(x) > limit:
        raise ValueError(f"{where}: a text of {len(x):,} characters (at most {limit:,})")
    return x


def _mapping(x: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(x, dict):
        raise ValueError(f"{where}: {type(x).__name__} where a mapping belongs")
    return x


def _list(x: Any, where: str, limit: int) -> list[Any]:
    if not isinstance(x, list):
        raise ValueError(f"{where}: {type(x).__name__} where a list belongs")
    if len(x) > limit:
        raise ValueError(f"{where}: {len(x):,} items (at most {limit:,})")
    return x


def check_assessment(a: Any, where: str) -> None:
    """An assessment as :meth:`stiction.Assessment.to_dict` writes it."""
    a = _mapping(a, where)
    if a.get("verdict") not in _VERDICTS:
        raise ValueError(f"{where}.verdict: not one of {', '.join(sorted(_VERDICTS))}")
    _text(a.get("reason"), f"{where}.reason")
    for key, value in a.items():
        at = f"{where}.{key}"
        if key in _NUMBERS:
            if value is not None:
                _number(value, at, finite=False)
        elif key in ("oscillating", "multi_jump"):
            if not isinstance(value, bool):
                raise ValueError(f"{at}: {type(value).__name__} where true/false belongs")
        elif key == "cycles_used":
            _integer(value, at, 0, MAX_WINDOW)
        elif key == "warnings":
            for k, w in enumerate(_list(value, at, MAX_ITEMS)):
                _text(w, f"{at}[{k}]")
        elif key == "evidence":
            for k, e in enumerate(_list(value, at, MAX_ITEMS)):
                _evidence(e, f"{at}[{k}]")
        elif key not in _FIELDS:
            raise ValueError(f"{at}: not a field of an assessment")
        elif key not in ("verdict", "reason"):  # a field added since: plain values only
            _plain(value, at)


def _plain(value: Any, where: str) -> None:
    """None, true/false, a number, a bounded text, or a bounded list of those."""
    items = _list(value, where, MAX_ITEMS) if isinstance(value, list) else [value]
    for v in items:
        if isinstance(v, str):
            _text(v, where)
        elif v is not None and not isinstance(v, bool | int | float):
            raise ValueError(f"{where}: {type(v).__name__} where a plain value belongs")


def _evidence(e: Any, where: str) -> None:
    e = _mapping(e, where)
    if set(e) != {"test", "value", "vote", "note"}:
        raise ValueError(f"{where}: fields {sorted(e)}, expected test, value, vote, note")
    _text(e["test"], f"{where}.test", 200)
    if e["value"] is not None:
        _number(e["value"], f"{where}.value", finite=False)
    _integer(e["vote"], f"{where}.vote", -1, 1)
    _text(e["note"], f"{where}.note")


def _result(r: Any, where: str) -> None:
    r = _mapping(r, where)
    missing = {"assessment", "seq", "t", "window_fill", "samples"} - set(r)
    if missing:
        raise ValueError(f"{where}: no {', '.join(sorted(missing))}")
    check_assessment(r["assessment"], f"{where}.assessment")
    _integer(r["seq"], f"{where}.seq", 0, MAX_SEQ)
    _number(r["t"], f"{where}.t", 0.0, MAX_WALL)
    _number(r["window_fill"], f"{where}.window_fill", 0.0, 1.0)
    _integer(r["samples"], f"{where}.samples", 0, MAX_WINDOW)
    if "judged" in r:  # since issue 35 item 5 (the release before ignores it)
        _number(r["judged"], f"{where}.judged", 0.0, MAX_WALL)
    if "hold" in r:
        _integer(r["hold"], f"{where}.hold", 0, 2)
    if "pv_swing" in r:  # since issue 39 (the release before ignores them)
        _number(r["pv_swing"], f"{where}.pv_swing", 0.0, 1e15)
    if "since" in r:
        _number(r["since"], f"{where}.since", 0.0, MAX_WALL)


def _loop(entry: Any, where: str) -> None:
    entry = _mapping(entry, where)
    _text(entry.get("name"), f"{where}.name", 1000)
    if "seq" in entry:
        _integer(entry["seq"], f"{where}.seq", 0, MAX_SEQ)
    if "result" in entry:
        _result(entry["result"], f"{where}.result")


def check_header(header: Any, max_loops: int) -> None:
    """Every field of a state file's header (format and version checked before); at most
    ``max_loops`` loop entries in all."""
    h = _mapping(header, "header")
    _number(h.get("saved_wall"), "saved_wall", 0.0, MAX_WALL)
    _number(h.get("saved_proc"), "saved_proc", -1e15, 1e15)
    if not isinstance(h.get("clean", False), bool):
        raise ValueError("clean: not true/false")
    if h.get("analysis_interval_wall_s") is not None:
        _number(h["analysis_interval_wall_s"], "analysis_interval_wall_s", 1e-6, 1e12)
    if "order" in h:  # the loops in config order (read when valid; older files lack it)
        for k, name in enumerate(_list(h["order"], "order", max_loops)):
            _text(name, f"order[{k}]", 1000)
    if "plant" in h:  # per loop (group number, role, source): read by the report only
        plant = _mapping(h["plant"], "plant")
        if len(plant) > max_loops:
            raise ValueError(f"plant: more than {max_loops:,} loops")
        for name, v in plant.items():
            if not isinstance(v, list) or len(v) != 3:
                raise ValueError("plant: an entry that is not [group, role, source]")
            _integer(v[0], f"plant[{name[:40]!r}].group", 0, 255)
            _text(v[1], f"plant[{name[:40]!r}].role", 20)
            _text(v[2], f"plant[{name[:40]!r}].source", 1000)
    banks = _list(h.get("banks"), "banks", max_loops)
    loops = 0
    for k, bank in enumerate(banks):
        b = _mapping(bank, f"banks[{k}]")
        _number(b.get("ts"), f"banks[{k}].ts", 1e-9, 1e9)
        _integer(b.get("size"), f"banks[{k}].size", 2, MAX_WINDOW)
        if "position" in b and not isinstance(b["position"], bool):
            raise ValueError(f"banks[{k}].position: {type(b['position']).__name__} where "
                             f"true/false belongs")
        if "position" in b and h.get("version") == 1:
            raise ValueError(f"banks[{k}].position: not in a version 1 file")
        entries = _list(b.get("loops"), f"banks[{k}].loops", max_loops)
        loops += len(entries)
        if loops > max_loops:
            raise ValueError(f"banks: more than {max_loops:,} loops")
        for c, entry in enumerate(entries):
            _loop(entry, f"banks[{k}].loops[{c}]")
