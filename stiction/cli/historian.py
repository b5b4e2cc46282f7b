"""Reading a window as process historians export it, for ``stiction analyze``.

A historian's CSV export is read as it is: the delimiter sniffed from the header and the
first rows (``,``, ``;`` or tab; an Excel ``sep=;`` first line is obeyed), decimal commas
and thousands separators (``1,118.5`` or ``1.118,5``: the decimal mark decided per column
from the whole column's evidence, :mod:`.decimals`; a column that reads two ways is refused,
naming both readings), a UTF-8 or UTF-16 byte-order mark, Windows-1252 when the
file is not UTF-8, column names matched without regard to case, time stamps as seconds or
as ISO 8601 and other common date-times (:data:`DATE_FORMATS`), and text cells in OP or PV
("I/O Timeout", "Shutdown", "Bad") as gaps, counted. Rows go on a grid of the median sample
time (:func:`on_grid`); time stamps that wander off it are refused. Every problem is a
:class:`~stiction.cli._common.UsageError` that names the file, the line or column, and what
to do.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from . import decimals
from ._common import UsageError

__all__ = ["DATE_FORMATS", "TIME_COLUMNS", "Table", "add_reading_options", "column", "grid",
           "numbers", "on_grid", "read_table", "times", "write_export"]

DELIMITERS = (",", ";", "\t")
TIME_COLUMNS = ("t", "time", "timestamp", "datetime", "date time", "date")
"""Column names taken for the time when ``--time`` is not given (any case), in this order."""
DATE_FORMATS = (
    "%d.%m.%Y %H:%M:%S", "%d.%m.%Y %H:%M",            # 01.03.2024 06:00:00
    "%d/%m/%Y %H:%M:%S", "%d/%m/%Y %H:%M",            # 01/03/2024 06:00:00
    "%m/%d/%Y %H:%M:%S", "%m/%d/%Y %H:%M",            # 03/01/2024 06:00:00
    "%m/%d/%Y %I:%M:%S %p", "%m/%d/%Y %I:%M %p",      # 3/1/2024 6:00:00 AM
    "%d-%b-%Y %H:%M:%S", "%d-%b-%y %H:%M:%S",          # 01-Mar-2024 06:00:00 (PI)
    "%Y/%m/%d %H:%M:%S",                               # 2024/03/01 06:00:00
)
"""Date-time forms tried after ISO 8601 (``2024-03-01 06:00:00``, ``...T06:00:00.5Z``,
``...+01:00``), each also with fractional seconds; day-first and month-first both parse
as the one under which time never goes back."""
JITTER = 0.25  # a time stamp further than this share of the sample time off the grid is off it
OFF_GRID = 0.01  # share of rows that may be off the grid before the stamps are refused
_EXAMPLES = ("seconds, or dates like 2024-03-01 06:00:00, 2024-03-01T06:00:00Z, "
             "01.03.2024 06:00:00, 3/1/2024 6:00:00 AM")


@dataclasses.dataclass(frozen=True)
class Table:
    """A read export: the header, the data rows with their line numbers, how it was read."""

    path: Path
    header: list[str]
    rows: list[list[str]]
    lines: list[int]
    delimiter: str
    decimal: str | None = None
    """The decimal mark given (``--decimal``), else None: decided per column."""
    notes: tuple[str, ...] = ()


def add_reading_options(p: argparse.ArgumentParser) -> None:
    """The options of how an export is read, for every command that reads one."""
    p.add_argument("--decimal", choices=(decimals.POINT, decimals.COMMA), default=None,
                   help="the decimal mark, when the file cannot tell (every number like "
                   "1,118 or 1.118); default: decided per column from its numbers")


def read_table(path: Path, *, decimal: str | None = None) -> Table:
    """The file's header and rows (empty lines skipped); ``decimal`` the decimal mark
    (default: decided per column, :func:`numbers`)."""
    text, notes = _text(path)
    lines = text.splitlines()
    first = 0
    sep = None
    if lines and lines[0].lower().startswith("sep=") and len(lines[0]) in (5, 6):
        sep, first = lines[0][4:] or "\t", 1  # Excel's hint line
    body = lines[first:]
    if not any(line.strip() for line in body):
        raise UsageError(f"{path}: empty file (need a header row naming the columns)")
    delimiter = sep or _sniff(body)
    reader = csv.reader(body, delimiter=delimiter)
    header: list[str] | None = None
    rows: list[list[str]] = []
    at: list[int] = []
    for row in reader:
        if not any(c.strip() for c in row):
            continue
        if header is None:
            header = [c.strip() for c in row]
            continue
        rows.append(row)
        at.append(reader.line_num + first)
    assert header is not None
    return Table(path, header, rows, at, delimiter, decimal, tuple(notes))


def _text(path: Path) -> tuple[str, list[str]]:
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from exc
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):  # Excel's "Unicode text"
        return raw.decode("utf-16"), []
    try:
        return raw.decode("utf-8-sig"), []
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace"), [
            f"{path.name} is not UTF-8: read as Windows-1252"]


def _sniff(lines: Sequence[str]) -> str:
    """The delimiter that splits the header and the first rows into the same number of
    cells, the most cells; else the one most frequent in the header."""
    sample = [line for line in lines if line.strip()][:50]
    best, most = None, 1
    for d in DELIMITERS:
        counts = [len(r) for r in csv.reader(sample, delimiter=d)]
        if counts and counts[0] > most and all(c == counts[0] for c in counts[1:]):
            best, most = d, counts[0]
    return best or max(DELIMITERS, key=sample[0].count)


def column(table: Table, name: str, option: str) -> int:
    """The index of column ``name``: its exact name, else its name in any case."""
    if name in table.header:
        return table.header.index(name)
    same = [i for i, h in enumerate(table.header) if h.casefold() == name.casefold()]
    if len(same) == 1:
        return same[0]
    shown = ", ".join(table.header)
    if same:
        raise UsageError(f"{table.path}: columns {', '.join(repr(table.header[i]) for i in same)}"
                         f" differ only in case; give {option} with the exact name")
    raise UsageError(f"{table.path}: no column {name!r} (columns: {shown}); give {option} "
                     "COL with one of them")


def time_column(table: Table) -> int | None:
    """The first of :data:`TIME_COLUMNS` the header has (any case), or None."""
    folded = [h.casefold() for h in table.header]
    return next((folded.index(n) for n in TIME_COLUMNS if n in folded), None)


def _cells(table: Table, col: int) -> list[str]:
    return [row[col] if col < len(row) else "" for row in table.rows]


def read_numbers(table: Table, col: int, cells: Sequence[str]
                 ) -> tuple[decimals.Column, str | None]:
    """Column ``col``'s cells as numbers with its decimal mark (the one given, else the one
    its cells show, else the one the other columns show, :func:`decimals.decide`), and the
    note that says how they were read when it is not plain: thousands grouped, or the mark
    taken from elsewhere. A column that reads two ways, or holds both styles, is refused."""
    own = decimals.tally(cells, decisive=True)
    others: list[tuple[int, dict[str, int]]] = []
    if table.decimal is None and decimals.POINT not in own and decimals.COMMA not in own \
            and decimals.BOTH in own:
        others = [(j, decimals.tally(_cells(table, j), decisive=True))
                  for j in range(len(table.header)) if j != col]
    usual = "." if table.delimiter == "," else None  # a CSV proper: decimal points
    try:
        mark, settled = (table.decimal, "given") if table.decimal is not None else \
            decimals.decide(own, [t for _, t in others], usual)
    except decimals.Ambiguous as exc:
        raise UsageError(_ambiguous(table, col, cells, exc.row)) from None
    got = decimals.read_column(cells, mark)
    if got.other is not None and settled is None:
        first = own[mark]
        point, comma = (first, got.other) if mark == "." else (got.other, first)
        raise UsageError(
            f"{table.path}: column {table.header[col]!r} mixes decimal marks: "
            f"{cells[point].strip()!r} (line {table.lines[point]}) has a decimal point, "
            f"{cells[comma].strip()!r} (line {table.lines[comma]}) a decimal comma; give "
            "--decimal . or --decimal , (cells of the other style become gaps, counted)")
    name = table.header[col]
    cell = cells[own[decimals.BOTH]].strip() if decimals.BOTH in own else ""
    read = f"column {name!r}: {cell!r} read as {decimals.value(cell, mark):.10g}: "
    if settled == "others":
        j, t = next((j, t) for j, t in others if mark in t)
        return got, read + (f"{mark!r} is the decimal mark of this export (column "
                            f"{table.header[j]!r}: {_cells(table, j)[t[mark]].strip()!r})")
    if settled == "usual" and decimals.grouped(cell, mark):
        return got, read + "'.' is the decimal mark of a ','-separated file (give " \
            "--decimal , if ',' is)"
    if got.grouped is None:
        return got, None
    example = cells[got.grouped].strip()
    other = "," if mark == "." else "."
    sep = f"{other!r}" if other in example else "a space"
    return got, (f"column {name!r}: thousands grouped ({example!r} read as "
                 f"{decimals.value(example, mark):.10g}: {sep} groups thousands, {mark!r} is "
                 "the decimal mark)")


def _ambiguous(table: Table, col: int, cells: Sequence[str], row: int) -> str:
    cell = cells[row].strip()
    p, c = decimals.value(cell, "."), decimals.value(cell, ",")
    sep = "," if "," in cell else "."
    grouping, decimal = f"{sep!r} grouping thousands", f"{sep!r} the decimal mark"
    first, second = (f"{p:.10g} with {grouping}", f"{c:.10g} with {decimal}") if sep == "," \
        else (f"{p:.10g} with {decimal}", f"{c:.10g} with {grouping}")
    return (f"{table.path}: column {table.header[col]!r}: {cell!r} (line {table.lines[row]}) "
            f"reads as {first} or as {second}, and no number in the file tells which; give "
            f"--decimal . (reads {p:.10g}) or --decimal , (reads {c:.10g})")


def numbers(table: Table, col: int) -> tuple[np.ndarray, str | None]:
    """Column ``col`` as numbers, text cells as gaps (NaN), and the note that counts them
    and says how the numbers were read when they group thousands (:func:`read_numbers`)."""
    got, how = read_numbers(table, col, _cells(table, col))
    text = got.text
    name = table.header[col]
    if text and not np.isfinite(got.values).any():
        first = next(iter(text))
        raise UsageError(f"{table.path}: column {name!r} holds no numbers (e.g. {first!r}); "
                         "is it the right column? Give --op/--pv COL")
    if not text:
        return got.values, how
    kinds = ", ".join(f"{k!r} {n}" for k, n in text.most_common(3))
    more = "" if len(text) <= 3 else f" and {len(text) - 3} other texts"
    gaps = f"column {name!r}: {sum(text.values())} text cells treated as gaps: {kinds}{more}"
    return got.values, gaps if how is None else f"{how}; {gaps}"


def times(table: Table, col: int) -> np.ndarray:
    """Column ``col`` as seconds: numbers as they are, date-times as Unix seconds (UTC when
    the stamp names no zone)."""
    cells = [row[col].strip() if col < len(row) else "" for row in table.rows]
    name = table.header[col]
    for i, c in enumerate(cells):
        if not c:
            raise UsageError(f"{table.path}: line {table.lines[i]}, column {name!r}: no time; "
                             "every row needs one (or give --ts S for rows at a fixed "
                             "interval)")
    if cells and decimals.is_number(cells[0]):  # seconds
        got, _ = read_numbers(table, col, cells)
        if not got.text:
            return got.values
    parsed = _dates(cells)
    if parsed is None:
        i = _first_bad(cells)
        raise UsageError(f"{table.path}: line {table.lines[i]}, column {name!r}: not a time: "
                         f"{cells[i]!r}; times may be {_EXAMPLES}; or give --ts S for rows "
                         "at a fixed interval")
    return parsed


def _dates(cells: Sequence[str]) -> np.ndarray | None:
    """Unix seconds of every cell under the first form that reads them all (of two that
    do, the one under which time never goes back), or None."""
    fallback = None
    for form in ("iso", *DATE_FORMATS):
        got = _parse_all(cells, form)
        if got is None:
            continue
        if np.all(np.diff(got) >= 0):
            return got
        fallback = fallback if fallback is not None else got
    return fallback


def _parse_all(cells: Sequence[str], form: str) -> np.ndarray | None:
    out = np.empty(len(cells))
    zoned = None
    for i, c in enumerate(cells):
        stamp = _parse(c, form)
        if stamp is None:
            return None
        aware = stamp.tzinfo is not None
        if zoned is None:
            zoned = aware
        elif zoned != aware:
            return None  # some with a zone, some without: not one clock
        out[i] = (stamp if aware else stamp.replace(tzinfo=dt.UTC)).timestamp()
    return out


def _parse(cell: str, form: str) -> dt.datetime | None:
    try:
        if form == "iso":
            if cell[:4].isdigit() and len(cell) >= 10 and cell[4] == "-":
                return dt.datetime.fromisoformat(cell)
            return None
        try:
            return dt.datetime.strptime(cell, form)
        except ValueError:
            frac = cell.rpartition(".")[2]
            if not frac[:1].isdigit() or "%S" not in form:
                raise
            return dt.datetime.strptime(cell, form.replace("%S", "%S.%f"))
    except ValueError:
        return None


def _first_bad(cells: Sequence[str]) -> int:
    """The first cell no form reads (for the message)."""
    for i, c in enumerate(cells):
        if not decimals.is_number(c) and all(_parse(c, f) is None
                                              for f in ("iso", *DATE_FORMATS)):
            return i
    return 0


def on_grid(path: Path, name: str, t: np.ndarray, op: np.ndarray, pv: np.ndarray
            ) -> tuple[float, np.ndarray, np.ndarray, list[str]]:
    """OP and PV on a regular grid of the median sample time (:func:`grid`)."""
    ts, (grid_op, grid_pv), notes = grid(path, name, t, (op, pv))
    return ts, grid_op, grid_pv, notes


def grid(path: Path, name: str, t: np.ndarray, series: Sequence[np.ndarray]
         ) -> tuple[float, list[np.ndarray], list[str]]:
    """Put the rows on a regular grid of the median sample time: repeated time stamps keep
    their last row, missing rows become gaps (NaN), as a historian export needs. Stamps
    more than a quarter sample off the grid in over 1 % of the rows are refused (the
    historian exported recorded, compressed values, not samples at a fixed interval)."""
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise UsageError(f"{path}: time goes backwards at line {int(back[0]) + 3} "
                         f"({t[back[0]]:g} -> {t[back[0] + 1]:g} s in column {name!r}): sort "
                         "the rows by time; a daylight-saving change in local time? Export "
                         "in UTC or with the zone offset")
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0:
        raise UsageError(f"{path}: column {name!r} holds one time only; give --ts S")
    ts = float(np.median(steps))
    k = np.round((t - t[0]) / ts).astype(np.int64)
    if k[-1] + 1 > 50 * t.size:
        raise UsageError(f"{path}: time stamps too irregular to put on a grid of {ts:g} s")
    off = np.abs(t - t[0] - k * ts)
    n_off = int(np.count_nonzero(off > JITTER * ts))
    if n_off > OFF_GRID * t.size:
        raise UsageError(
            f"{path}: time stamps irregular: {n_off} of {t.size} rows more than a quarter of "
            f"the {ts:g} s sample time off its grid (steps {steps.min():g} to "
            f"{steps.max():g} s): the historian exported recorded (compressed) values; "
            "export interpolated values at a fixed interval, or give --ts S if the rows are "
            "equally spaced")
    out = []
    for x in series:
        g = np.full(int(k[-1]) + 1, np.nan)
        g[k] = x  # a repeated index keeps the last row
        out.append(g)
    repeated = t.size - np.unique(k).size
    missing = int(k[-1]) + 1 - np.unique(k).size
    notes = []
    if float(off.max()) > 0.02 * ts:
        notes.append(f"time stamps jitter up to {float(off.max()):.3g} s around the {ts:g} s "
                     "grid: each row put on the nearest grid point")
    if repeated:
        notes.append(f"{repeated} rows repeat a time stamp (on a {ts:g} s grid): the last "
                     "of each kept")
    if missing:
        notes.append(f"{missing} samples missing from the {ts:g} s time grid: treated as gaps")
    return ts, out, notes


EXPORT_START = dt.datetime(2024, 3, 1, 6, 0, 0, tzinfo=dt.UTC)
"""The first time stamp :func:`write_export` writes."""


def write_export(fh: TextIO, tag: str, t: np.ndarray, op: np.ndarray, pv: np.ndarray) -> None:
    """OP and PV as a historian exports them (``stiction simulate --historian TAG``): what
    :func:`read_table` reads without options but ``--op TAG.OP --pv TAG.PV``."""
    w = csv.writer(fh, delimiter=";", lineterminator="\r\n")
    w.writerow(["Timestamp", f"{tag}.OP", f"{tag}.PV"])
    for i, (ti, o, v) in enumerate(zip(t.tolist(), op.tolist(), pv.tolist(), strict=True)):
        stamp = (EXPORT_START + dt.timedelta(seconds=ti)).strftime("%Y-%m-%d %H:%M:%S")
        pv_cell = "I/O Timeout" if i % 500 == 250 else f"{v:.4f}".replace(".", ",")
        w.writerow([stamp, f"{o:.4f}".replace(".", ","), pv_cell])
