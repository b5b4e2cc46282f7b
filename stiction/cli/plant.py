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

from .._assessment import Assessment
from ..diagnosis.analyze import analyze
from ..plant import PlantAssessment, analyze_plant
from ..plant.spectra import spectra
from . import historian
from ._common import Subparsers, UsageError, pyplot

__all__ = ["add_plant", "loop_columns"]

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
        "members, the source ranking) and every loop's verdict: a loop that only carries a "
        "cycle from elsewhere is 'propagated'.")
    p.add_argument("file", type=Path, help="CSV file with a header row")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column (default: t, time, timestamp, "
                   "datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--integrating", nargs="+", default=[], metavar="TAG",
                   help="loops whose process integrates (levels)")
    p.add_argument("--cascade", nargs="+", default=[], metavar="OUTER=INNER",
                   help="cascades: the outer loop's OP is the inner loop's setpoint")
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
    notes = list(table.notes)
    if args.time is not None:
        t_col: int | None = historian.column(table, args.time, "--time")
    elif args.ts is None:
        t_col = historian.time_column(table)
        if t_col is None:
            raise UsageError(f"{args.file}: no time column (columns: {', '.join(table.header)})"
                             "; give --time COL or --ts S")
    else:
        t_col = None
    header = [h for i, h in enumerate(table.header) if i != t_col]
    cols = [i for i in range(len(table.header)) if i != t_col]
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
                                           historian.times(table, t_col),
                                           [series[j] for j in keys])
        series = dict(zip(keys, gridded, strict=True))
        notes += more
    else:
        ts = float(args.ts)
    return (ts, {tag: (series[o], series[p]) for tag, (o, p) in loops.items()},
            {name: series[j] for name, j in others.items() if j in series}, notes)


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


def _cmd_plant(args: argparse.Namespace) -> int:
    ts, loops, indicators, notes = _read(args)
    processes, cascades = _options(args, loops)
    before = {tag: analyze(op, pv, ts=ts, process=processes[tag])
              for tag, (op, pv) in loops.items()}
    view = analyze_plant(loops, ts=ts, indicators=indicators, assessments=before,
                         processes=processes, cascades=cascades)
    after = view.apply(before)
    if args.json:
        print(json.dumps(as_json(view, after, notes)))
    else:
        _print(view, after, notes)
    if args.plot is not None:
        spectral_map(args.plot, ts, loops, view)
    return 0


def as_json(view: PlantAssessment, after: dict[str, Assessment], notes: list[str]
            ) -> dict[str, Any]:
    """``groups`` (each with ``loops``, ``period_s``, ``source_ranking``) and ``loops``
    (each with ``loop``, ``verdict``, ``confidence``, ``group``, ``role``)."""
    return {
        "groups": [{
            "group": g.number, "period_s": g.period_s, "loops": list(g.loops),
            "indicators": [m.name for m in g.members if m.kind == "indicator"],
            "strength": {m.name: round(m.strength, 4) for m in g.members},
            "source": g.source, "external": g.external, "reason": g.reason,
            "source_ranking": [{"loop": e.loop, "score": round(e.score, 4),
                                "valve_gain": e.valve_gain, "kano": e.kano,
                                "episodes": e.episodes, "confidence": e.confidence,
                                "harmonics": round(e.harmonics, 4)} for e in g.ranking],
        } for g in view.groups],
        "loops": [{"loop": tag, "verdict": str(a.verdict), "confidence": a.confidence,
                   "group": view.roles[tag].group, "role": view.roles[tag].role,
                   "reason": a.reason} for tag, a in after.items()],
        "warnings": notes,
    }


def _print(view: PlantAssessment, after: dict[str, Assessment], notes: list[str]) -> None:
    if not view.groups:
        print("no oscillation shared by two loops or more")
    for g in view.groups:
        where = f"source {g.source}" if g.source else "no loop is its source"
        print(f"group {g.number}: period {g.period_s:.0f} s, {len(g.loops)} loops, {where}")
        print("  members: " + ", ".join(f"{m.name} {m.strength:.0%}" for m in g.members))
        print("  source ranking: " + ", ".join(f"{e.loop} {e.score:.2f}" for e in g.ranking))
        print(f"  {g.reason}")
    print()
    width = max(len(t) for t in after)
    for tag, a in after.items():
        r = view.roles[tag]
        place = f"group {r.group} {r.role}" if r.group else "-"
        conf = "" if a.confidence is None else f"{a.confidence:.2f}"
        print(f"{tag:<{width}}  {a.verdict!s:<20} {conf:>5}  {place:<16} {a.reason}")
    for n in notes:
        print(f"warning: {n}")


def spectral_map(path: Path, ts: float, loops: dict[str, tuple[np.ndarray, np.ndarray]],
                 view: PlantAssessment) -> None:
    """Loops x frequency, each loop's OP and PV power (normalised, log scale), the groups'
    periods marked."""
    names = list(loops)
    rows = np.array([s for tag in names for s in loops[tag]])
    spec = spectra(np.nan_to_num(rows - np.nanmean(rows, axis=1, keepdims=True)))
    power = spec.power[0::2] + spec.power[1::2]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 0.4 * len(names) + 2))
    period = 1.0 / np.maximum(spec.freqs, 1e-12) * ts
    ax.pcolormesh(period[::-1], np.arange(len(names)), np.log10(power[:, ::-1] + 1e-6),
                  shading="nearest")
    ax.set_xscale("log")
    ax.set_yticks(np.arange(len(names)), names)
    ax.set_xlabel("period, s")
    for g in view.groups:
        ax.axvline(g.period_s, color="w", lw=1, ls="--")
        rows_in = [names.index(m) for m in g.loops]
        ax.scatter([g.period_s] * len(rows_in), rows_in, color="w", marker="o", s=30,
                   edgecolors="k", zorder=3)
        ax.text(g.period_s, len(names) - 0.45, f" group {g.number}"
                + (f": {g.source}" if g.source else ": no loop source"), color="w", fontsize=8)
    ax.set_title("power of each loop's OP and PV (log scale); dots: the groups' members",
                 pad=12)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
