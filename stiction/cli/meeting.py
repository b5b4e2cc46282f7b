"""``stiction analyze --manifest LIST --report report.html``: the maintenance meeting's page
from a unit's exports (:mod:`stiction.report`): the files' loops worst first, in the order
``--json`` lists them, and a section per suspect valve with the window analysed (its OP and
PV on the export's own time, the OP-PV plot), the size, the valve's travel where a position
column was read, and the crew's findings where ``--findings`` gave them."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..report import Finding, Listed, Report, Trend, render
from ._common import UsageError

__all__ = ["listed", "write_report"]


def _start(clock: Any) -> str:
    if clock is None:
        return ""
    if clock.zone is None:
        return f"{clock.start:g} s"
    return dt.datetime.fromtimestamp(clock.start, clock.zone).strftime("%Y-%m-%d %H:%M %Z")


def _trend(got: Any) -> Trend | None:
    d = got.details
    if d.op is None or d.pv is None or d.op.size < 2:
        return None
    unit = "% of span" if got.op_range == (0.0, 100.0) else "OP units"
    return Trend(np.arange(d.op.size) * got.ts, np.asarray(d.op), np.asarray(d.pv),
                 _start(got.clock), unit, "PV units")


def _travel(a: Any) -> str:
    if a.position_use is None:
        return ""
    note = next((e.note for e in a.evidence if e.test == "travel"), "")
    return f"position column read, {a.position_use.replace('_', ' ')}: {note}".rstrip(": ")


def listed(name: str, row: Any, findings: Sequence[Finding] = ()) -> Listed:
    """One row of the batch as the report lists it."""
    if row.shown is None:
        return Listed(name, None, None, "error", reason=str(row.error or ""),
                      error=str(row.error or ""), source=str(row.file))
    got, s = row.analysed, row.shown
    a = got.assessment if got is not None else None
    return Listed(name, s.get("rank"), s.get("suspicion"), str(s["verdict"]),
                  s.get("confidence"), str(s.get("reason", "")),
                  None if a is None else a.sizes(), "", "", tuple(findings), (),
                  None if got is None else _trend(got), "" if a is None else _travel(a),
                  "site" if "Calibration: this site's" in str(s.get("reason", ""))
                  else "shipped", source=str(row.file))


def write_report(path: Path, rows: Sequence[tuple[str, Any]], *, notes: Sequence[str] = (),
                 findings: dict[str, list[Finding]] | None = None) -> None:
    """The page for ``rows`` (loop name, batch row) in the list's order, to ``path``."""
    loops = tuple(listed(name, row, (findings or {}).get(name, ())) for name, row in rows)
    analysed = sum(1 for lp in loops if not lp.error)
    report = Report("Valves to check, worst first", loops,
                    (f"{analysed} of {len(loops)} file(s) analysed by stiction analyze",
                     *notes), generated=f"stiction analyze --report, "
                                        f"{dt.datetime.now().strftime('%Y-%m-%d %H:%M')}")
    try:
        path.write_text(render(report), encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"--report {path}: cannot write: {exc.strerror or exc}") from exc
