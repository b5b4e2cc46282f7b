"""The list of a unit's loops for ``stiction analyze --manifest LIST``: one row per file, its
own options in optional columns over the command line's.

A CSV file with a header row (``,``, ``;`` or tab separated, UTF-8 or Windows-1252, column
names in any case): ``file`` (a path relative to the list's folder, or absolute) and any of
:data:`COLUMNS`. A cell overrides the command line's option for its file, an empty cell falls
back to it. A row the list cannot use (a number that is none, ``op_lo`` without ``op_hi``,
``ts`` beside ``time``) is named ``LIST:LINE`` with what is wrong, and listed as that loop's
error; the other rows are analysed. A list without a ``file`` column, with a column it does
not know, or without any row is refused whole."""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from pathlib import Path
from typing import Any

from ..diagnosis.analyze import PROCESSES
from . import decimals, stamps
from ._common import UsageError
from .loop import LoopOptions
from .table import read_text

__all__ = ["COLUMNS", "Loop", "read_manifest"]

COLUMNS = ("file", "ts", "process", "op_lo", "op_hi", "kp", "delay", "op", "pv", "position",
           "time", "sp", "tz", "decimal", "loop", "priority")
"""The columns a manifest may have (any case, any order); ``file`` is required."""


@dataclasses.dataclass(frozen=True)
class Loop:
    """One file to analyse, named ``label`` as the outputs show it, with its options; or,
    where its manifest row is unusable, ``error`` saying why."""

    label: str
    path: Path
    options: LoopOptions
    error: str | None = None
    name: str = ""  # the loop (the ``loop`` column; "": the file's name), for --findings
    priority: float = 1.0  # its weight in the list worst first (:mod:`.ranking`)


def read_manifest(path: Path, base: LoopOptions) -> list[Loop]:
    """The loops ``path`` lists, each with ``base`` under its own cells."""
    text = read_text(path, named=" (--manifest)")[0]
    first = next((line for line in text.splitlines() if line.strip()), None)
    if first is None:
        raise UsageError(f"{path}: empty manifest (need a header row naming the column 'file')")
    delimiter = max((",", ";", "\t"), key=first.count)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    rows = []  # (line, cells): a quoted cell may hold a line break
    line = 1
    for row in reader:
        if any(c.strip() for c in row):
            rows.append((line, row))
        line = reader.line_num + 1
    head_line, header = rows[0]
    names = [h.strip().casefold() for h in header]
    for name in names:
        if name not in COLUMNS:
            raise UsageError(f"{path}:{head_line}: unknown column {name!r} (a manifest has "
                             f"'file' and any of {', '.join(COLUMNS[1:])})")
        if names.count(name) > 1:
            raise UsageError(f"{path}:{head_line}: column {name!r} twice")
    if "file" not in names:
        raise UsageError(f"{path}:{head_line}: no column 'file' (columns: {', '.join(header)})")
    if len(rows) < 2:
        raise UsageError(f"{path}: no loop listed under the header")
    return [_loop(path, n, names, row, base) for n, row in rows[1:]]


def _loop(manifest: Path, line: int, names: list[str], row: list[str], base: LoopOptions
          ) -> Loop:
    where = f"{manifest}:{line}"
    if len(row) > len(names):
        return Loop(where, manifest, base, f"{where}: {len(row)} cells, the header names "
                                           f"{len(names)}")
    cells = {n: c.strip() for n, c in zip(names, row, strict=False) if c.strip()}
    if "file" not in cells:
        return Loop(where, manifest, base, f"{where}: no file named in column 'file'")
    path = manifest.parent / cells["file"]
    try:
        options = dataclasses.replace(base, **_changes(cells))
        priority = _number(cells, "priority", lambda v: v > 0, "> 0") \
            if "priority" in cells else 1.0
    except ValueError as exc:
        return Loop(str(path), path, base, f"{where}: {exc}", cells.get("loop", ""))
    return Loop(str(path), path, options, name=cells.get("loop", ""), priority=priority)


def _changes(cells: dict[str, str]) -> dict[str, Any]:
    """The options a row's cells set (ValueError names the column and what is wrong)."""
    got: dict[str, Any] = {k: cells[k] for k in ("op", "pv", "position", "sp") if k in cells}
    if "ts" in cells and "time" in cells:
        raise ValueError("give 'ts' (rows at a fixed interval) or 'time' (the time column), "
                         "not both")
    if "time" in cells:
        got["time"], got["ts"] = cells["time"], None
    if "ts" in cells:
        got["ts"], got["time"] = _number(cells, "ts", lambda v: v > 0, "> 0"), None
    if "kp" in cells:
        got["kp"] = _number(cells, "kp", lambda v: v != 0, "not 0")
    if "delay" in cells:
        got["delay"] = _number(cells, "delay", lambda v: v >= 0, ">= 0")
    if "tz" in cells:
        try:
            got["tz"] = stamps.parse_tz(cells["tz"])
        except ValueError as exc:
            raise ValueError(f"column 'tz': {exc}") from None
    if "decimal" in cells:
        if cells["decimal"] not in (decimals.POINT, decimals.COMMA):
            raise ValueError(f"column 'decimal': {cells['decimal']!r} is not '.' or ','")
        got["decimal"] = cells["decimal"]
    if "process" in cells:
        process = cells["process"].casefold()
        if process not in PROCESSES:
            raise ValueError(f"column 'process': {cells['process']!r} is not one of "
                             f"{', '.join(PROCESSES)}")
        got["process"] = process
    if ("op_lo" in cells) != ("op_hi" in cells):
        given, missing = ("op_lo", "op_hi") if "op_lo" in cells else ("op_hi", "op_lo")
        raise ValueError(f"column {given!r} without {missing!r}: give both (the OP at 0 % and "
                         "100 % valve span) or neither")
    if "op_lo" in cells:
        lo = _number(cells, "op_lo", lambda v: True, "")
        hi = _number(cells, "op_hi", lambda v: v > lo, f"> op_lo ({lo:g})")
        got["op_range"] = (lo, hi)
    return got


def _number(cells: dict[str, str], name: str, ok: Any, must: str) -> float:
    text = cells[name]
    try:  # a decimal comma as a ';'-separated list from a spreadsheet writes it
        v = float(text.replace(",", ".") if "." not in text else text)
    except ValueError:
        raise ValueError(f"column {name!r}: {text!r} is not a number") from None
    if not math.isfinite(v) or not ok(v):
        raise ValueError(f"column {name!r}: {text!r} must be {must or 'finite'}")
    return v
