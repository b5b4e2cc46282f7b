"""`stiction analyze`: one loop's window from a CSV file, its verdict and evidence; several
files, or a manifest of them, one row per loop (:mod:`.batch`).

What one file shows is :mod:`.loop`'s (:func:`~.loop.analyze_file`, :func:`~.loop.view`):
the same dict for ``--json`` of one file and for each object of a batch's array."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .._assessment import Assessment, Verdict
from ..diagnosis.network import NAME as NETWORK
from ..diagnosis.reasons import WHAT
from . import batch, historian, ranking, site
from ._common import Subparsers, UsageError
from .every import duration as every_duration
from .loop import SP_COLUMNS, LoopOptions, analyze_file, bursts, view
from .plot import plot_analysis
from .report import duration, number

__all__ = ["VOTE_WORDS", "add_analyze", "bursts", "view"]


# ------------------------------------------------------------------------------- analyze
def add_analyze(sub: Subparsers) -> None:
    p = sub.add_parser(
        "analyze",
        help="assess CSV windows of OP/PV: oscillation, stiction, fd and fs; one file or a "
        "whole unit",
        description="Reads OP and PV (and time) columns of a CSV file with a header row, "
        "as a process historian exports it, and prints the assessment: ',' ';' or tab "
        "separated, decimal commas, column names in any case, times in seconds or as "
        "date-times (ISO 8601 and common forms). Empty, 'nan' and text cells ('I/O "
        "Timeout', 'Shutdown') in OP or PV are missing samples (gaps), counted, and so are "
        "samples a quality column (Quality, Confidence) marks bad; a long export "
        "(DateTime,TagName,Value) is read one column per tag. Several files, or --manifest: "
        "one row per loop (a file that cannot be read is listed with its error, the others "
        "analysed; exit 0 if any loop was analysed); --every: one row per window.",
    )
    p.add_argument("files", type=Path, nargs="*", metavar="FILE",
                   help="CSV file with a header row; several: one row per loop")
    p.add_argument("--manifest", type=Path, default=None, metavar="LIST",
                   help="a CSV list of the loops: column 'file' (relative to the list's "
                   "folder) and optionally " + ", ".join(f"'{c}'" for c in batch.COLUMNS[1:])
                   + "; a cell overrides the option for its file, an empty one falls back "
                   "to it")
    p.add_argument("--op", default="op", help="OP column (default op; any case)")
    p.add_argument("--pv", default="pv", help="PV column (default pv; any case)")
    p.add_argument("--position", default=None, metavar="COL",
                   help="the valve's position column, in OP's units (a smart positioner's "
                   "travel): stiction is then measured from it (band and slip) instead of "
                   "inferred from PV; unusable (gaps, never reverses): OP and PV decide")
    s = p.add_mutually_exclusive_group()
    s.add_argument("--sp", default=None, metavar="COL",
                   help="the setpoint column (default: " + ", ".join(SP_COLUMNS) + ", any "
                   "case, where the file has one): the window is judged on its longest "
                   "stretch between setpoint steps, as a step is not the valve's jump")
    s.add_argument("--no-sp", dest="no_sp", action="store_true",
                   help="do not read a setpoint column even where the file has one")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column: seconds or date-times "
                   "(default: t, time, timestamp, datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--kp", type=float, default=None, help="process gain, PV units per OP "
                   "unit (an integrating process: PV units per s per OP unit); gives fs and "
                   "the jump")
    p.add_argument("--delay", type=float, default=0.0, help="process dead time, s")
    p.add_argument("--process", choices=("self-regulating", "integrating"),
                   default="self-regulating", help="self-regulating: PV settles after the "
                   "valve moves (flow, pressure, temperature; the default); integrating: PV "
                   "ramps while the valve is off balance (a level). A level read as "
                   "self-regulating sizes nothing right")
    p.add_argument("--op-range", dest="op_range", nargs=2, type=float, metavar=("LO", "HI"),
                   default=None, help="OP at 0 %% and 100 %% valve span, to report sizes in %% of "
                   "span (default: sizes in OP units; no OP range is assumed)")
    p.add_argument("--from", dest="start", default=None, metavar="TIME",
                   help="analyse from this time on, written as the file writes its times "
                   "(e.g. '2024-03-01 08:10:00', or seconds); with --ts, seconds from the "
                   "first row")
    p.add_argument("--to", dest="stop", default=None, metavar="TIME",
                   help="analyse up to this time (as --from)")
    p.add_argument("--every", type=every_duration, default=None, metavar="DURATION",
                   help="one verdict per window of this length (8h, 1d, 30min, 1w), a table "
                   "over time: windows aligned to midnight of the first day in the file's "
                   "zone, each analysed as --from/--to would; an end shorter than half a "
                   "window is left out, said so (default: one verdict for the whole file)")
    historian.add_reading_options(p)
    p.add_argument("--json", action="store_true", help="print the assessment as one JSON "
                   "object; several files: one JSON array of them, each with its 'file'")
    p.add_argument("--csv", type=Path, default=None, metavar="OUT",
                   help="write the assessments to OUT for a spreadsheet: one row per file, "
                   "the --json keys flattened (size.fd, evidence.kano.vote, ...), an "
                   "'error' column for a file not analysed")
    p.add_argument("--plot", type=Path, default=None, help="draw OP, PV and the fit to "
                   "FILE.png; several files: a folder, one PNG per file (its name's stem)")
    ranking.add_options(p)  # --sort, --top, --findings, --report (several files)
    site.add_option(p)  # --no-site (several files)
    p.set_defaults(handler=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    if (args.manifest is not None or len(args.files) > 1 or args.report is not None
            or args.every is not None):
        return batch.run(args)
    if not args.files:
        raise UsageError("analyze: give a CSV file, several, or --manifest LIST")
    path = args.files[0]
    got = analyze_file(path, LoopOptions.from_args(args))
    if args.json:
        print(json.dumps(got.shown))
    else:
        _print(got.assessment, got.shown)
    if args.plot is not None:
        plot_analysis(args.plot, got.details, got.ts, got.op_range, got.clock)
        if not args.json:
            print(f"wrote {args.plot}")
    if args.csv is not None:
        batch.write_csv(args.csv, [batch.Row(path, got.shown)])
        if not args.json:
            print(f"wrote {args.csv}")
    return 0


def _print(a: Assessment, shown: dict[str, Any]) -> None:
    print(f"verdict: {a.verdict}")
    print(f"reason:  {a.reason}")
    print(f"means:   {a.verdict.advice}")
    for key, val in shown.items():
        if key not in {"verdict", "reason", "warnings", "evidence", "size", "weighed",
                       "stretch", "site", "site_share"} and val is not None:
            print(f"  {key}: {_value(key, val, a)}")
    if any(e.test == NETWORK and e.value is not None for e in a.evidence):
        print(f"  site: {site.said(shown)}")  # how the shape network's reading was taken
    size = shown["size"]
    for key in ("fd", "fs", "jump", "band", "slip") if size else ():
        if size.get(key) is not None:
            print(f"  {key}: {number(size[key])} {size['unit']}")
    if size and "cycles_used" in size:
        print(f"  cycles_used: {size['cycles_used']} (limit cycles whose jumps were read)")
    if a.evidence:
        print("  evidence (test, value, vote, what it saw):")
    for e in a.evidence:
        value = "-" if e.value is None else number(e.value, 3)
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


def _value(key: str, val: Any, a: Assessment) -> str:
    """A field of the assessment as the text output shows it: a period as a duration, yes
    or no for a flag, where the analysis found no regular cycle under a verdict that
    judged one it found irregular, that."""
    if key == "period_s":
        return duration(val)
    if key == "oscillating":
        if val:
            return "yes, a regular cycle"
        judged = a.verdict in (Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED)
        return "no regular cycle (the verdict judged an irregular one)" if judged else "no"
    if isinstance(val, bool):
        return "yes" if val else "no"
    return number(val) if isinstance(val, float) else str(val)


VOTE_WORDS = {1: "stiction", -1: "not stiction", 0: "cannot tell"}
"""A vote as the table prints it (the reason's words: :data:`~stiction.diagnosis.reasons.
VOTES`)."""
