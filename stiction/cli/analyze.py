"""`stiction analyze`: one loop's window from a CSV file, its verdict and evidence."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from .._assessment import Assessment
from ..diagnosis.analyze import analyze_details
from . import historian
from ._common import Subparsers, UsageError
from .plot import plot_analysis, window_clock


# ------------------------------------------------------------------------------- analyze
def add_analyze(sub: Subparsers) -> None:
    p = sub.add_parser(
        "analyze",
        help="assess one CSV window of OP/PV: oscillation, stiction (SI), fd and fs",
        description="Reads OP and PV (and time) columns of a CSV file with a header row, "
        "as a process historian exports it, and prints the assessment: ',' ';' or tab "
        "separated, decimal commas, column names in any case, times in seconds or as "
        "date-times (ISO 8601 and common forms). Empty, 'nan' and text cells ('I/O "
        "Timeout', 'Shutdown') in OP or PV are missing samples (gaps), counted.",
    )
    p.add_argument("file", type=Path, help="CSV file with a header row")
    p.add_argument("--op", default="op", help="OP column (default op; any case)")
    p.add_argument("--pv", default="pv", help="PV column (default pv; any case)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column: seconds or date-times "
                   "(default: t, time, timestamp, datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--kp", type=float, default=None, help="process gain, PV units per OP unit")
    p.add_argument("--delay", type=float, default=0.0, help="process dead time, s")
    p.add_argument("--process", choices=("self-regulating", "integrating"),
                   default="self-regulating")
    p.add_argument("--op-range", dest="op_range", nargs=2, type=float, metavar=("LO", "HI"),
                   default=None, help="OP at 0 %% and 100 %% valve span, to report sizes in %% of "
                   "span (default: sizes in OP units; no OP range is assumed)")
    historian.add_reading_options(p)
    p.add_argument("--json", action="store_true", help="print the assessment as one JSON object")
    p.add_argument("--plot", type=Path, default=None, help="draw OP, PV and the fit to FILE.png")
    p.set_defaults(handler=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    table = historian.read_table(args.file, decimal=args.decimal, tz=args.tz)
    notes = list(table.notes)
    op_col = historian.column(table, args.op, "--op")
    pv_col = historian.column(table, args.pv, "--pv")
    if args.time is not None:
        t_col: int | None = historian.column(table, args.time, "--time")
    elif args.ts is None:
        t_col = historian.time_column(table)
        if t_col is None:
            raise UsageError(f"{args.file}: no time column 't' (columns: "
                             f"{', '.join(table.header)}); give --time COL or --ts S")
    else:
        t_col = None
    if len(table.rows) < 2:
        raise UsageError(f"{args.file}: {len(table.rows)} samples, need at least 2")
    op, op_note = historian.numbers(table, op_col)
    pv, pv_note = historian.numbers(table, pv_col)
    notes += [n for n in (op_note, pv_note) if n]
    t = None if t_col is None else historian.times(table, t_col)
    if t is not None and t_col is not None:
        ts, op, pv, grid = historian.on_grid(args.file, table.header[t_col], t, op, pv)
        notes += grid
    else:
        ts = args.ts
    clock = window_clock(t, ts, op, pv)
    op_range = None if args.op_range is None else tuple(args.op_range)
    d = analyze_details(op, pv, ts=ts, kp=args.kp, delay=args.delay, process=args.process,
                        op_range=op_range)
    a = dataclasses.replace(d.assessment, warnings=(*notes, *d.assessment.warnings))
    if args.json:
        print(json.dumps(view(a)))
    else:
        print(f"verdict: {a.verdict}")
        print(f"reason:  {a.reason}")
        shown = view(a)
        for key, val in shown.items():
            if key not in {"verdict", "reason", "warnings", "evidence", "size"} and \
                    val is not None:
                print(f"  {key}: {val:.4g}" if isinstance(val, float) else f"  {key}: {val}")
        size = shown["size"]
        for key in ("fd", "fs", "jump") if size else ():
            if size[key] is not None:
                print(f"  {key}: {size[key]:.4g} {size['unit']}")
        if size and "cycles_used" in size:
            print(f"  cycles_used: {size['cycles_used']} (limit cycles whose jumps were read)")
        if a.evidence:
            print("  evidence (test, value, vote, what it saw):")
        for e in a.evidence:
            value = "-" if e.value is None else f"{e.value:.3g}"
            vote = {1: "stiction", -1: "not stiction"}.get(e.vote, "cannot tell")
            print(f"    {e.test:<14} {value:>8}  {vote:<12}  {e.note}")
        for w in a.warnings:
            print(f"  warning: {w}")
    if args.plot is not None:
        plot_analysis(args.plot, d, ts, op_range, clock)
        if not args.json:
            print(f"wrote {args.plot}")
    return 0


SIZE_FIELDS = ("fd", "fs", "jump", "fd_op", "fs_op", "cycles_used")


def view(a: Assessment) -> dict[str, Any]:
    """What ``analyze`` prints: the assessment's fields with the sizes in one unit under
    ``size`` (:meth:`stiction.Assessment.sizes`: unit, fd, fs, jump and, when read from
    the limit cycle, cycles_used; None when not sized) instead of fractions beside OP
    units."""
    out = {k: v for k, v in a.to_dict().items() if k not in SIZE_FIELDS}
    sizes = a.sizes()
    out["size"] = None if sizes is None else sizes.to_dict()
    return out
