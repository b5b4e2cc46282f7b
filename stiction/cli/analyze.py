"""`stiction analyze`: one loop's window from a CSV file, its verdict and evidence."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._assessment import Assessment
from ..diagnosis.analyze import analyze_details
from ._common import Subparsers, UsageError
from .plot import plot_analysis


# ------------------------------------------------------------------------------- analyze
def add_analyze(sub: Subparsers) -> None:
    p = sub.add_parser(
        "analyze",
        help="assess one CSV window of OP/PV: oscillation, stiction (SI), fd and fs",
        description="Reads OP and PV (and time) columns of a CSV file with a header row and "
        "prints the assessment. Empty or 'nan' cells are missing samples.",
    )
    p.add_argument("file", type=Path, help="CSV file with a header row")
    p.add_argument("--op", default="op", help="OP column (default op)")
    p.add_argument("--pv", default="pv", help="PV column (default pv)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column, s (default t)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--kp", type=float, default=None, help="process gain, PV units per OP unit")
    p.add_argument("--delay", type=float, default=0.0, help="process dead time, s")
    p.add_argument("--process", choices=("self-regulating", "integrating"),
                   default="self-regulating")
    p.add_argument("--op-range", dest="op_range", nargs=2, type=float, metavar=("LO", "HI"),
                   default=None, help="OP at 0 %% and 100 %% valve span, to report sizes in %% of "
                   "span (default: sizes in OP units; no OP range is assumed)")
    p.add_argument("--json", action="store_true", help="print the assessment as one JSON object")
    p.add_argument("--plot", type=Path, default=None, help="draw OP, PV and the fit to FILE.png")
    p.set_defaults(handler=_cmd_analyze)


def _read_columns(path: Path, names: Sequence[str]) -> dict[str, np.ndarray]:
    """Numeric columns ``names`` of a CSV file; empty and 'nan' cells become NaN."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:  # a byte-order mark is common
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read {path}: {exc}") from exc
    if not rows:
        raise UsageError(f"{path}: empty file (need a header row)")
    header = [h.strip() for h in rows[0]]
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name not in header:
            raise UsageError(f"{path}: no column {name!r} (columns: {', '.join(header)})")
        col = header.index(name)
        vals = np.empty(len(rows) - 1)
        for i, row in enumerate(rows[1:]):
            cell = row[col].strip() if col < len(row) else ""
            try:
                vals[i] = float(cell) if cell else np.nan
            except ValueError:
                raise UsageError(f"{path}: line {i + 2}, column {name!r}: not a number: "
                                 f"{cell!r}") from None
        out[name] = vals
    return out


def _cmd_analyze(args: argparse.Namespace) -> int:
    time_col = args.time if args.time is not None else ("t" if args.ts is None else None)
    names = [args.op, args.pv] + ([time_col] if time_col else [])
    try:
        cols = _read_columns(args.file, names)
    except UsageError as exc:
        if time_col == "t" and args.time is None and "no column 't'" in str(exc):
            raise UsageError(f"{exc}; give --time COL or --ts S") from None
        raise
    op, pv = cols[args.op], cols[args.pv]
    if op.size < 2:
        raise UsageError(f"{args.file}: {op.size} samples, need at least 2")
    notes: list[str] = []
    if time_col:
        ts, op, pv, notes = _on_grid(args.file, time_col, cols[time_col], op, pv)
    else:
        ts = args.ts
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
        plot_analysis(args.plot, d, ts, op_range)
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


def _on_grid(path: Path, name: str, t: np.ndarray, op: np.ndarray, pv: np.ndarray
             ) -> tuple[float, np.ndarray, np.ndarray, list[str]]:
    """Put the rows on a regular grid of the median sample time: repeated time stamps keep
    their last row, missing rows become gaps (NaN), as a historian export needs."""
    if not np.all(np.isfinite(t)):
        line = int(np.flatnonzero(~np.isfinite(t))[0]) + 2
        raise UsageError(f"{path}: column {name!r} has a missing time at line {line}")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise UsageError(f"{path}: time goes backwards at line {int(back[0]) + 3} "
                         f"({t[back[0]]:g} -> {t[back[0] + 1]:g})")
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0:
        raise UsageError(f"{path}: column {name!r} holds one time only; give --ts S")
    ts = float(np.median(steps))
    k = np.round((t - t[0]) / ts).astype(np.int64)
    notes = []
    if k[-1] + 1 > 50 * t.size:
        raise UsageError(f"{path}: time stamps too irregular to put on a grid of {ts:g} s")
    grid_op = np.full(int(k[-1]) + 1, np.nan)
    grid_pv = grid_op.copy()
    grid_op[k], grid_pv[k] = op, pv  # a repeated index keeps the last row
    repeated = t.size - np.unique(k).size
    missing = grid_op.size - np.unique(k).size
    if repeated:
        notes.append(f"{repeated} rows repeat a time stamp (on a {ts:g} s grid): the last "
                     "of each kept")
    if missing:
        notes.append(f"{missing} samples missing from the {ts:g} s time grid: treated as gaps")
    return ts, grid_op, grid_pv, notes
