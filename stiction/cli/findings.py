"""``stiction analyze --findings FILE``: what a crew found at a unit's valves, to fit the
unit's own calibration of the confidence offline (:mod:`stiction.ranking.calibration`).

The gateway's findings file (docs/configuration.md, "Findings"): a CSV file with a header
naming ``loop`` and ``finding`` (``stiction``, ``deadband``, ``ok`` or ``other``) in any case
and order, optionally ``date`` (YYYY-MM-DD) and the gateway's other columns (ignored here);
``,``, ``;`` or tab separated, UTF-8, UTF-16 or Windows-1252. A row's ``loop`` names a file
of the batch: the manifest's ``loop`` column, else the file's name without its folder and
suffix. A row that cannot be used is named (``FILE:LINE``) and skipped.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
from pathlib import Path

from ._common import UsageError
from .table import read_text

__all__ = ["FINDINGS", "Found", "read_findings"]

FINDINGS = ("stiction", "deadband", "ok", "other")
KNOWN = ("loop", "date", "finding", "fd", "fs", "deadband", "resolution", "by", "note")


@dataclasses.dataclass(frozen=True)
class Found:
    """One usable row: the loop, whether the valve was found sticking, the date ('' when
    the row gives none), the line."""

    loop: str
    finding: str
    date: str
    line: int

    @property
    def sticky(self) -> bool:
        return self.finding == "stiction"


def read_findings(path: Path) -> tuple[list[Found], list[str]]:
    """The usable rows of ``path`` and one line per row skipped (UsageError: no usable
    header)."""
    text, _notes = read_text(path, named=" (--findings)")
    lines = [(n + 1, line) for n, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise UsageError(f"{path}: empty findings file (a header naming 'loop' and "
                         "'finding', then one finding per row)")
    head_line, first = lines[0]
    delimiter = max((",", ";", "\t"), key=first.count)
    rows = list(csv.reader([line for _, line in lines], delimiter=delimiter))
    header = [c.strip().casefold() for c in rows[0]]
    for need in ("loop", "finding"):
        if need not in header:
            raise UsageError(f"{path}:{head_line}: no column {need!r} (a findings file has "
                             f"{', '.join(KNOWN)})")
    out, problems = [], []
    at = {name: header.index(name) for name in ("loop", "finding", "date") if name in header}
    for (n, _), row in zip(lines[1:], rows[1:], strict=True):
        cells = {k: (row[i].strip() if i < len(row) else "") for k, i in at.items()}
        finding = cells["finding"].casefold()
        where = f"{path}:{n}"
        if not cells["loop"]:
            problems.append(f"{where}: no loop named: skipped")
        elif finding not in FINDINGS:
            problems.append(f"{where}: finding {cells['finding']!r} is not one of "
                            f"{', '.join(FINDINGS)}: skipped")
        elif cells.get("date") and not _date(cells["date"]):
            problems.append(f"{where}: date {cells['date']!r} is not YYYY-MM-DD: skipped")
        else:
            out.append(Found(cells["loop"], finding, cells.get("date", ""), n))
    return out, problems


def _date(text: str) -> bool:
    try:
        dt.date.fromisoformat(text[:10])
    except ValueError:
        return False
    return True
