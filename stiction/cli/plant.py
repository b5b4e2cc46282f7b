"""`stiction plant`: a wide historian export of many loops, the oscillations they share,
each one's source, and every loop's verdict with the plant view.

Loops are found from column pairs ``TAG.OP`` and ``TAG.PV`` (also ``TAG_OP``, ``TAG OP``,
``TAG.MV`` or ``TAG.OUT`` for the output, any case); ``TAG.SP`` columns belong to their loop
and are not used; every other numeric column is an indicator (a measured signal of no loop).
The file is read as ``stiction analyze`` reads one (:mod:`.historian`).
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

_ROLE = re.compile(r"^(?P<tag>.+?)[._ ](?P<kind>op|mv|out|pv|sp)$", re.IGNORECASE)
_KIND = {"op": "op", "mv": "op", "out": "op", "pv": "pv", "sp": "sp"}


def add_plant(sub: Subparsers) -> None:
    p = sub.add_parser(
        "plant",
        help="many loops of one export: which share an oscillation, which loop is its source",
        description="Reads a wide CSV export (one column per signal, as a historian writes "
        "it; see `stiction analyze --help` for the formats), finds the loops from TAG.OP / "
        "TAG.PV column pairs (TAG_OP, TAG.MV, TAG.OUT, any case), uses the other numeric "
        "columns as indicators, and prints the oscillations the loops share (period, "
        "members, the source ranking with its evidence) and every loop's verdict: a loop "
        "that only carries a cycle from elsewhere is 'propagated'. `stiction simulate "
        "--plant NAME` writes such an export of a simulated plant.")
    p.add_argument("file", type=Path, help="CSV file with a header row")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column (default: t, time, timestamp, "
                   "datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--integrating", nargs="+", default=[], metavar="TAG",
                   help="loops whose process integrates (levels)")
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
    """Loops (tag -> OP and PV column) and indicators (name -> column) of a header."""
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
    return ({spelled[key]: (c["op"], c["pv"]) for key, c in pairs.items()},
            {h: i for i, h in enumerate(header) if i not in used})


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
                         f"(or TAG_OP, TAG.MV; any case) (columns: {', '.join(table.header)})")
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


def _options(args: argparse.Namespace, loops: dict[str, Any]
             ) -> tuple[dict[str, str], dict[str, str]]:
    unknown = [t for t in args.integrating if t not in loops]
    cascades = {}
    for item in args.cascade:
        outer, sep, inner = item.partition("=")
        if not sep:
            raise UsageError(f"--cascade {item!r}: give OUTER=INNER")
        unknown += [t for t in (outer, inner) if t not in loops]
        cascades[outer] = inner
    if unknown:
        raise UsageError(f"no loop {', '.join(map(repr, unknown))} in the file (loops: "
                         f"{', '.join(loops)})")
    return ({t: "integrating" if t in args.integrating else "self-regulating" for t in loops},
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
