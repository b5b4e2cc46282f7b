"""`stiction plant`: a wide historian export of many loops, the oscillations they share,
each one's source, and every loop's verdict with the plant view.

Loops are found from column pairs ``TAG.OP`` and ``TAG.PV`` (also ``TAG_OP``, ``TAG OP``,
``TAG.MV`` or ``TAG.OUT`` for the output, any case), and from historians' path-style tags
(:func:`loop_columns`: Ignition's ``[default]U2/FIC101/OP``, ``U2:FIC101:PV``, DeltaV's
``FIC101/PID1/OUT.CV``); ``TAG.SP`` columns belong to their loop and are not used; every other
numeric column is an indicator (a measured signal of no loop), and a column named like a
loop's signal whose loop has no partner column is one too, with a warning. The file is read
as ``stiction analyze`` reads one (:mod:`.historian`).
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..diagnosis.analyze import analyze
from ..plant import analyze_plant
from . import historian
from ._common import Subparsers, UsageError
from .plantout import as_json, print_text, spectral_map

__all__ = ["add_plant", "as_json", "loop_columns"]

_ROLE = re.compile(r"^(?P<tag>.+?)[._ /:\\|](?P<kind>op|mv|out|pv|sp)(?:[./](?:cv|value))?$",
                   re.IGNORECASE)
"""A loop's signal: its tag, a separator ('.', '_', ' ', '/', ':', '\\' or '|') and its role,
with DeltaV's ``.CV`` (or ``.VALUE``) after it."""
_PROVIDER = re.compile(r"^\[[^\]]*\]")
"""Ignition's tag provider before a tag path (``[default]``): not part of the loop's name."""
_KIND = {"op": "op", "mv": "op", "out": "op", "pv": "pv", "sp": "sp"}


def add_plant(sub: Subparsers) -> None:
    p = sub.add_parser(
        "plant",
        help="many loops of one export: which share an oscillation, which loop is its source",
        description="Reads a wide CSV export (one column per signal, as a historian writes "
        "it; see `stiction analyze --help` for the formats), finds the loops from TAG.OP / "
        "TAG.PV column pairs (TAG_OP, TAG.MV, TAG.OUT, any case; also historians' tag paths "
        "such as Ignition's [default]U2/FIC101/OP or DeltaV's FIC101/PID1/OUT.CV), uses the "
        "other numeric columns as indicators, and prints the oscillations the loops share (period, "
        "members, the source ranking with its evidence) and every loop's verdict: a loop "
        "that only carries a cycle from elsewhere is 'propagated'. `stiction simulate "
        "--plant NAME` writes such an export of a simulated plant.")
    p.add_argument("file", type=Path, help="CSV file with a header row")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column (default: t, time, timestamp, "
                   "datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--integrating", nargs="+", default=[], metavar="TAG",
                   help="loops whose process integrates (levels); a tag as the report names "
                   "it, in any case, or the last part of its path where that is one loop's "
                   "(LIC301 for U2/LIC301)")
    p.add_argument("--cascade", nargs="+", default=[], metavar="OUTER=INNER",
                   help="cascades: the outer loop's OP is the inner loop's setpoint")
    p.add_argument("--units", nargs="+", default=[], metavar="UNIT=TAG,TAG",
                   help="plant units: groups form within a unit only (loops of independent "
                   "units that happen to share a period are not one group); tags not named "
                   "are one unit among themselves")
    p.add_argument("--unit-prefix", action="store_true",
                   help="each tag's unit is the text before its first '.', '/' or ':' "
                   "(U1.FIC101 is in unit U1)")
    historian.add_reading_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", type=Path, default=None,
                   help="draw the spectral map (loops x frequency, the groups marked) to FILE")
    p.set_defaults(handler=_cmd_plant)


def loop_columns(header: list[str]) -> tuple[dict[str, tuple[int, int]], dict[str, int]]:
    """Loops (tag -> OP and PV column) and indicators (name -> column) of a header. A tag
    is named as its columns spell it, less a tag provider in brackets (``[default]``) where
    the names stay apart without it."""
    found: dict[str, dict[str, int]] = {}  # tag in any case -> kind -> column
    spelled: dict[str, str] = {}  # ... -> the tag as its first column spells it
    for i, name in enumerate(header):
        m = _ROLE.match(name.strip())
        if m:
            key = m["tag"].casefold()
            spelled.setdefault(key, m["tag"])
            found.setdefault(key, {})[_KIND[m["kind"].lower()]] = i
    pairs = {key: c for key, c in found.items() if "op" in c and "pv" in c}
    used = {i for c in pairs.values() for i in c.values()}
    others = {i: h for i, h in enumerate(header) if i not in used}
    full = [spelled[key] for key in pairs] + list(others.values())
    short = [_PROVIDER.sub("", n) for n in full]
    if len({n.casefold() for n in short}) < len(short) or not all(short):
        short = full  # without the provider two names would be one
    loops = dict(zip(short, [(c["op"], c["pv"]) for c in pairs.values()], strict=False))
    return loops, dict(zip(short[len(pairs):], others, strict=True))


def unpaired(header: list[str], indicators: dict[str, int]) -> list[str]:
    """The warnings for indicators named like a loop's OP or PV (:data:`_ROLE`) whose loop
    has no partner column: read as indicators, maybe not what the export meant."""
    out = []
    for i in indicators.values():
        name = header[i]
        m = _ROLE.match(name.strip())
        if m and _KIND[m["kind"].lower()] != "sp":
            other = "PV" if _KIND[m["kind"].lower()] == "op" else "OP"
            out.append(f"column {name!r} is named like a loop's {m['kind'].upper()} but the "
                       f"file has no {other} column of {m['tag']!r}: read as an indicator")
    return out


def _read(args: argparse.Namespace) -> tuple[float, dict[str, tuple[np.ndarray, np.ndarray]],
                                             dict[str, np.ndarray], list[str]]:
    table = historian.read_table(args.file, decimal=args.decimal, tz=args.tz)
    t_col = historian.time_choice(table, args.time, args.ts)
    t = None
    if t_col is not None and table.size >= 2:
        table, t = historian.oldest_first(table, t_col)
    notes = list(table.notes)
    skip = {t_col, *(i for i, h in enumerate(table.header) if historian.is_quality(h))}
    header = [h for i, h in enumerate(table.header) if i not in skip]
    cols = [i for i in range(len(table.header)) if i not in skip]
    loops, others = loop_columns(header)
    if not loops:
        raise UsageError(f"{args.file}: no loop found: name the columns TAG.OP and TAG.PV "
                         "(or TAG_OP, TAG.MV, a tag path such as [default]U2/FIC101/OP; any "
                         f"case) (columns: {', '.join(table.header)})")
    notes += unpaired(header, others)
    series: dict[int, np.ndarray] = {}
    for j in sorted({c for pair in loops.values() for c in pair} | set(others.values())):
        x, note = historian.numbers(table, cols[j]) if j not in others.values() else \
            _indicator(table, cols[j])
        if x is not None:
            series[j] = x
            notes += [note] if note else []
    keys = sorted(series)
    if t_col is not None:
        ts, gridded, more = historian.grid(args.file, table.header[t_col],
                                           t if t is not None else historian.times(table, t_col),
                                           [series[j] for j in keys])
        series = dict(zip(keys, gridded, strict=True))
        notes += more
    else:
        ts = float(args.ts)
    return (ts, {tag: (series[o], series[p]) for tag, (o, p) in loops.items()},
            {name: series[j] for name, j in others.items() if j in series},
            historian.summarised(notes))


def _indicator(table: historian.Table, col: int) -> tuple[np.ndarray | None, str | None]:
    """An indicator column as numbers; a column of text (a status, a tag name) is no
    indicator."""
    try:
        return historian.numbers(table, col)
    except UsageError:
        return None, f"column {table.header[col]!r} holds no numbers: not used"


def _loop(tag: str, loops: dict[str, Any]) -> str | None:
    """The loop ``tag`` names: its name, in any case, or the last part of one loop's path."""
    if tag in loops:
        return tag
    same = [t for t in loops if t.casefold() == tag.casefold()] or \
        [t for t in loops if re.split(r"[./:\\|]", t)[-1].casefold() == tag.casefold()]
    return same[0] if len(same) == 1 else None


def _options(args: argparse.Namespace, loops: dict[str, Any]
             ) -> tuple[dict[str, str], dict[str, str]]:
    integrating = [_loop(t, loops) for t in args.integrating]
    unknown = [t for t, found in zip(args.integrating, integrating, strict=True) if not found]
    cascades = {}
    for item in args.cascade:
        outer, sep, inner = item.partition("=")
        if not sep:
            raise UsageError(f"--cascade {item!r}: give OUTER=INNER")
        pair = _loop(outer, loops), _loop(inner, loops)
        unknown += [t for t, found in zip((outer, inner), pair, strict=True) if not found]
        cascades[pair[0] or outer] = pair[1] or inner
    if unknown:
        raise UsageError(f"no loop {', '.join(map(repr, unknown))} in the file (loops: "
                         f"{', '.join(loops)})")
    return ({t: "integrating" if t in integrating else "self-regulating" for t in loops},
            cascades)


def _units(args: argparse.Namespace, loops: dict[str, Any], indicators: dict[str, Any]
           ) -> dict[str, str]:
    """Each signal's unit: ``--units UNIT=TAG,TAG ...`` or ``--unit-prefix`` (the text before
    a tag's first '.', '/' or ':'; a tag without one has no unit)."""
    units: dict[str, str] = {}
    if args.unit_prefix:
        for tag in [*loops, *indicators]:
            m = re.match(r"^([^./:]+)[./:].", tag)
            if m:
                units[tag] = m[1]
    known = {t.casefold(): t for t in [*loops, *indicators]}
    for item in args.units:
        unit, sep, tags = item.partition("=")
        if not sep or not unit or not tags:
            raise UsageError(f"--units {item!r}: give UNIT=TAG,TAG,...")
        for tag in tags.split(","):
            name = known.get(tag.strip().casefold())
            if name is None:
                raise UsageError(f"--units {item!r}: no loop or indicator {tag.strip()!r} in "
                                 f"the file (loops: {', '.join(loops)})")
            units[name] = unit
    return units


def _cmd_plant(args: argparse.Namespace) -> int:
    ts, loops, indicators, notes = _read(args)
    processes, cascades = _options(args, loops)
    units = _units(args, loops, indicators)
    before = {tag: analyze(op, pv, ts=ts, process=processes[tag])
              for tag, (op, pv) in loops.items()}
    view = analyze_plant(loops, ts=ts, indicators=indicators, assessments=before,
                         processes=processes, cascades=cascades, units=units)
    after = view.apply(before)
    if args.json:
        print(json.dumps(as_json(view, after, notes)))
    else:
        print_text(view, after, notes)
    if args.plot is not None:
        spectral_map(args.plot, ts, loops, view)
    return 0
