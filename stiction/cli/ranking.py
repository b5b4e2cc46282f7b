"""``stiction analyze`` of many files: worst first (``--sort``, ``--top``), the unit's own
calibration of the confidence from the crew's findings (``--findings``) and the maintenance
meeting's page (``--report``, :mod:`.report`).

Each loop's suspicion is :mod:`stiction.ranking.suspicion`'s: the confidence of stiction
(the unit's calibration of it with ``--findings``) times its ``priority`` (a manifest column,
default 1; offline the PV's span is not known, so its amplitude weighs 1). The rows are
listed worst first with their ``rank`` (``--sort file``: in the order given, the rank still
shown), the first ``--top N`` only. ``--json`` and ``--csv`` carry ``loop``, ``rank`` and
``suspicion``; a file not analysed is listed last, without a rank.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..ranking import SiteCalibration, Suspect, fit_site, rank, recalibrate, shipped
from ..report import Finding
from ._common import UsageError
from .findings import Found, read_findings
from .loop import rejudged
from .manifest import Loop

__all__ = ["add_options", "calibrate", "finish", "loop_name"]


def add_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sort", choices=("suspicion", "file"), default="suspicion",
                   help="several files: worst first by suspicion, with a rank column (the "
                   "default), or in the order given (file)")
    p.add_argument("--top", type=int, default=None, metavar="N",
                   help="several files: list only the first N rows (after --sort)")
    p.add_argument("--findings", type=Path, default=None, metavar="FILE",
                   help="the crew's findings (the gateway's findings file: loop, finding; "
                   "loop = the manifest's 'loop' or the file's name): fit the unit's own "
                   "calibration of the confidence and judge every file with it")
    p.add_argument("--report", type=Path, default=None, metavar="FILE",
                   help="several files: write the maintenance meeting's page, one HTML file "
                   "(the list worst first, a section per suspect valve)")


def loop_name(loop: Loop) -> str:
    """A file's loop: the manifest's ``loop`` cell, else the file's name without suffix."""
    return loop.name or Path(loop.path).stem


def calibrate(rows: list[Any], names: Sequence[str], found: Sequence[Found]
              ) -> tuple[list[Any], SiteCalibration]:
    """Fit the unit's calibration on ``found`` (each finding paired with every analysed
    file of its loop) and judge every row with it (:func:`stiction.ranking.recalibrate`)."""
    stiction_at, no_stiction_at = shipped()
    by_loop: dict[str, list[int]] = {}
    for k, (row, name) in enumerate(zip(rows, names, strict=True)):
        if row.analysed is not None:
            by_loop.setdefault(name, []).append(k)
    conf, sticky, keys = [], [], []
    for f in found:
        for k in by_loop.get(f.loop, []):
            c = rows[k].analysed.assessment.confidence
            if c is not None:
                conf.append(c)
                sticky.append(f.sticky)
                keys.append(f"{f.loop} {f.date} {rows[k].file}")
    cal = fit_site(np.array(conf, dtype=np.float64), np.array(sticky, dtype=bool), keys=keys,
                   stiction_at=stiction_at)
    return rejudged(rows, lambda a: recalibrate(a, cal, stiction_at=stiction_at,
                                                no_stiction_at=no_stiction_at)), cal


def _said(cal: SiteCalibration, used: int, given: int) -> str:
    head = (f"calibration of the confidence: {cal.name} ({cal.why}); {used} of {given} "
            "finding(s) matched an analysed file")
    if cal.site is None or cal.shipped is None:
        return head
    return (f"{head}; `stiction` calls on the findings: {cal.shipped.hits} of "
            f"{cal.shipped.calls} sticky with the shipped calibration, {cal.site.hits} of "
            f"{cal.site.calls} with the unit's (each held out)")


def finish(rows: list[Any], loops: Sequence[Loop], args: argparse.Namespace
           ) -> tuple[list[Any], list[str]]:
    """The batch's rows calibrated (``--findings``), ranked and sorted, the report written;
    returns the rows to show (``--top``) and lines for stderr."""
    if args.top is not None and args.top < 1:
        raise UsageError(f"--top {args.top}: give a number of rows, 1 or more")
    if getattr(args, "every", None) is not None:  # a table over time stays in time's order
        for option in ("findings", "report"):
            if getattr(args, option) is not None:
                raise UsageError(f"--{option} judges one window a file; --every gives a table "
                                 "over time: leave out one of them")
        return (rows if args.top is None else rows[: args.top]), []
    names = [loop_name(lp) for lp in loops]
    said: list[str] = []
    found: list[Found] = []
    if args.findings is not None:
        found, problems = read_findings(args.findings)
        said += problems
        rows, cal = calibrate(rows, names, found)
        known = set(names)
        said.append(_said(cal, sum(1 for f in found if f.loop in known), len(found)))
    # ranked by position (a loop's name may repeat: several files of one valve)
    order = rank([Suspect(str(k), str(r.shown["verdict"]) if r.shown else "error",
                          r.shown.get("confidence") if r.shown else None, None, lp.priority)
                  for k, (r, lp) in enumerate(zip(rows, loops, strict=True))])
    places = {int(r.name): r for r in order}
    annotated = []
    for k, row in enumerate(rows):
        r = places[k]
        shown = row if row.shown is None else dataclasses.replace(
            row, shown={"loop": names[k], "rank": r.rank, "suspicion": r.score, **row.shown})
        annotated.append((r.rank, names[k], shown))
    if args.sort == "suspicion":
        annotated.sort(key=lambda x: x[0])
    if args.report is not None:
        from .meeting import write_report

        crew: dict[str, list[Finding]] = {}
        for f in found:
            crew.setdefault(f.loop, []).append(Finding(f.date or "-", f.finding))
        write_report(args.report, [(n, row) for _r, n, row in annotated], notes=said,
                     findings=crew)
    out = [row for _r, _n, row in annotated]
    return (out if args.top is None else out[: args.top]), said



def warn(lines: Sequence[str]) -> None:
    for line in lines:
        print(f"stiction: {line}", file=sys.stderr)
