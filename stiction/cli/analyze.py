"""`stiction analyze`: one loop's window from a CSV file, its verdict and evidence.

Besides the assessment it prints what weighed most in the decision (the learned decision's
parts, which are not votes: :mod:`stiction.diagnosis.reasons`) and, where the window cycles
only in bursts, the stretch that cycles (:mod:`stiction.diagnosis.stretch`) in the file's own
time, with the ``--from``/``--to`` that analyse it alone."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from .._assessment import Assessment, Verdict
from ..diagnosis.analyze import Details, analyze_details
from ..diagnosis.reasons import WHAT
from ..diagnosis.stretch import Stretch, regular_stretch
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
    p.add_argument("--from", dest="start", default=None, metavar="TIME",
                   help="analyse from this time on, written as the file writes its times "
                   "(e.g. '2024-03-01 08:10:00', or seconds); with --ts, seconds from the "
                   "first row")
    p.add_argument("--to", dest="stop", default=None, metavar="TIME",
                   help="analyse up to this time (as --from)")
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
    secs = np.arange(len(table.rows)) * ts if t is None else t.seconds
    clock = FileTime(table, t_col, secs, ts)
    first, op, pv = clock.cut(args, op, pv)
    shown_from = window_clock(t, ts, op, pv)  # the plot's axis: the file's time
    shown_from = dataclasses.replace(shown_from, start=shown_from.start + first * ts)
    op_range = None if args.op_range is None else tuple(args.op_range)
    d = analyze_details(op, pv, ts=ts, kp=args.kp, delay=args.delay, process=args.process,
                        op_range=op_range)
    a = dataclasses.replace(d.assessment, warnings=(*notes, *d.assessment.warnings))
    stretch = bursts(d)
    if stretch is not None:
        a = dataclasses.replace(a, reason=a.reason + stretch.reason(ts))
    shown = view(a, d, clock.stretch(stretch, first + d.start) if stretch else None)
    if args.json:
        print(json.dumps(shown))
    else:
        _print(a, shown)
    if args.plot is not None:
        plot_analysis(args.plot, d, ts, op_range, shown_from)
        if not args.json:
            print(f"wrote {args.plot}")
    return 0


def _print(a: Assessment, shown: dict[str, Any]) -> None:
    print(f"verdict: {a.verdict}")
    print(f"reason:  {a.reason}")
    for key, val in shown.items():
        if key not in {"verdict", "reason", "warnings", "evidence", "size", "weighed",
                       "stretch"} and val is not None:
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
        vote = VOTE_WORDS[e.vote]
        print(f"    {e.test:<14} {value:>8}  {vote:<12}  {e.note}")
    if shown["weighed"]:
        print("  weighed in the decision (part of its log-odds, + for stiction; not votes):")
    for key, part in shown["weighed"].items():
        print(f"    {key:<14} {part:>+8.2f}  {WHAT.get(key, key)}")
    for w in a.warnings:
        print(f"  warning: {w}")
    if shown["stretch"]:
        st = shown["stretch"]
        print(f"  hint: analyse {st['from']} to {st['to']} alone: --from '{st['from']}' "
              f"--to '{st['to']}'")


VOTE_WORDS = {1: "stiction", -1: "not stiction", 0: "cannot tell"}
"""A vote as the table prints it (the reason's words: :data:`~stiction.diagnosis.reasons.
VOTES`)."""


def bursts(d: Details) -> Stretch | None:
    """The stretch that cycles, where the window's verdict rests on a cycle it found
    irregular (:func:`~stiction.diagnosis.stretch.regular_stretch`), and the stretch is a
    real part of the window; else None."""
    if d.op is None or d.pv is None or d.cycle is None or d.cycle.regular or \
            d.assessment.verdict not in BURST_VERDICTS:
        return None
    st = regular_stretch(d.op, d.pv)
    if st is None or st.stop - st.start > PART * d.op.size:
        return None
    return st


BURST_VERDICTS = (Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                  Verdict.NOT_OSCILLATING)
PART = 0.8
"""A stretch longer than this share of the window is the window: no hint."""


@dataclasses.dataclass(frozen=True)
class FileTime:
    """The file's own time for the samples: ``t`` (seconds) per row, ``ts`` the grid's
    sample time; the time column ``col`` of ``table`` (None: rows every ``ts`` from 0)."""

    table: historian.Table
    col: int | None
    t: np.ndarray
    ts: float

    def seconds(self, text: str, option: str) -> float:
        """``--from``/``--to``'s value in the file's seconds."""
        if self.col is None:
            try:
                return float(text)
            except ValueError:
                raise UsageError(f"{option} {text!r}: with --ts give seconds from the first "
                                 "row") from None
        row = [""] * len(self.table.header)
        row[self.col] = text
        one = dataclasses.replace(self.table, rows=[row], lines=[0])
        try:
            return float(historian.times(one, self.col).seconds[0])
        except UsageError:
            raise UsageError(f"{option} {text!r}: not a time as the file writes them "
                             f"(e.g. {self.text(0)!r})") from None

    def cut(self, args: argparse.Namespace, op: np.ndarray, pv: np.ndarray
            ) -> tuple[int, np.ndarray, np.ndarray]:
        """The samples between ``--from`` and ``--to`` (index of the first, op, pv)."""
        if args.start is None and args.stop is None:
            return 0, op, pv
        grid = self.t[0] + np.arange(op.size) * self.ts
        lo = -np.inf if args.start is None else self.seconds(args.start, "--from")
        hi = np.inf if args.stop is None else self.seconds(args.stop, "--to")
        keep = np.flatnonzero((grid >= lo - self.ts / 4) & (grid <= hi + self.ts / 4))
        if keep.size < 2:
            raise UsageError(f"--from/--to: {keep.size} samples between them (the file runs "
                             f"from {self.text(0)!r} to {self.text(op.size - 1)!r})")
        return int(keep[0]), op[keep[0] : keep[-1] + 1], pv[keep[0] : keep[-1] + 1]

    def text(self, k: int) -> str:
        """Sample ``k``'s time as the file wrote it (the nearest row's stamp)."""
        at = self.t[0] + k * self.ts
        if self.col is None:
            return f"{at:g}"
        i = int(np.argmin(np.abs(self.t - at)))
        return self.table.rows[i][self.col].strip()

    def stretch(self, st: Stretch, first: int) -> dict[str, Any]:
        """The stretch in the file's time (``first``: the window's first sample)."""
        return {"from": self.text(first + st.start), "to": self.text(first + st.stop - 1),
                "source": st.source, "period_s": st.period * self.ts,
                "regularity": st.regularity}


SIZE_FIELDS = ("fd", "fs", "jump", "fd_op", "fs_op", "cycles_used")


def view(a: Assessment, d: Details | None = None, stretch: dict[str, Any] | None = None
         ) -> dict[str, Any]:
    """What ``analyze`` prints: the assessment's fields with the sizes in one unit under
    ``size`` (:meth:`stiction.Assessment.sizes`: unit, fd, fs, jump and, when read from
    the limit cycle, cycles_used; None when not sized) instead of fractions beside OP
    units; ``weighed``: what weighed in the decision, strongest first (``d.parts``: each
    entry's part of the log-odds, + for stiction; not votes); ``stretch``: the stretch to
    analyse alone, in the file's time, or None."""
    out = {k: v for k, v in a.to_dict().items() if k not in SIZE_FIELDS}
    sizes = a.sizes()
    out["size"] = None if sizes is None else sizes.to_dict()
    parts = {} if d is None or d.parts is None else d.parts
    out["weighed"] = dict(sorted(parts.items(), key=lambda kv: -abs(kv[1])))
    out["stretch"] = stretch
    return out
