"""Reading a window as process historians export it, for ``stiction analyze``.

A historian's CSV export is read as it is: the file into a table by :mod:`.table` (the
delimiter sniffed, the encoding, a preamble, units rows and repeated headers), decimal commas
and thousands separators (``1,118.5`` or ``1.118,5``: the decimal mark decided per column
from the whole column's evidence, :mod:`.decimals`; a column that reads two ways is refused,
naming both readings), a UTF-8 or UTF-16 byte-order mark, Windows-1252 when the file is not
UTF-8, column names matched without regard to case, rows of units or descriptions under the
header and a header repeated where two exports were appended (skipped, said so), time stamps
as seconds (Unix milliseconds to nanoseconds read as such, said so) or as ISO 8601 and other
common date-times with or without a zone (:mod:`.stamps`), rows written newest first turned
round (said so), and text cells in OP or PV ("I/O Timeout", "Shutdown", "Bad") as gaps,
counted. Rows go on a grid of the median sample time (:mod:`.grid`); time stamps that wander
off it are refused. Every problem is a :class:`~stiction.cli._common.UsageError` that names
the file, the line or column, and what to do.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
from collections.abc import Sequence
from typing import TextIO

import numpy as np

from . import decimals, stamps
from ._common import UsageError
from .grid import Stamps, grid, on_grid
from .table import Table, add_reading_options, read_table

__all__ = ["DATE_COLUMNS", "TIME_COLUMNS", "Stamps", "Table", "add_reading_options", "column",
           "grid", "numbers", "oldest_first", "on_grid", "read_signals", "read_table",
           "time_choice", "times", "write_export"]

TIME_COLUMNS = ("t", "time", "timestamp", "datetime", "date time", "date")
"""Column names taken for the time when ``--time`` is not given (any case), in this order."""


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


def time_choice(table: Table, time: str | None, ts: float | None) -> int | None:
    """The time column a command reads: ``--time COL`` where given, else with no ``--ts``
    the first of :data:`TIME_COLUMNS` (:func:`time_column`; none: a usage error naming the
    columns), else None (rows every ``--ts`` seconds)."""
    if time is not None:
        return column(table, time, "--time")
    if ts is not None:
        return None
    t_col = time_column(table)
    if t_col is None:
        raise UsageError(f"{table.path}: no time column 't' (columns: "
                         f"{', '.join(table.header)}); give --time COL or --ts S")
    return t_col


@dataclasses.dataclass(frozen=True)
class Signals:
    """Columns read as numbers, on a regular grid where the file has a time column:
    ``series`` in the order asked, ``ts`` the sample time, ``stamps`` the time column read
    (None: rows every ``--ts``), ``t_col`` its index, ``notes`` how the file was read."""

    series: list[np.ndarray]
    ts: float
    stamps: Stamps | None
    t_col: int | None
    notes: list[str]
    table: Table
    """The table read, its rows oldest first (:func:`oldest_first`)."""


def read_signals(table: Table, columns: Sequence[tuple[str, str]], time: str | None,
                 ts: float | None) -> Signals:
    """The ``(name, option)`` columns of ``table`` as numbers, the time column chosen by
    :func:`time_choice`, at least two rows, put on the grid of the median sample time
    (:func:`grid`) where the file has times."""
    cols = [column(table, name, option) for name, option in columns]
    t_col = time_choice(table, time, ts)
    if len(table.rows) < 2:
        raise UsageError(f"{table.path}: {len(table.rows)} samples, need at least 2")
    t = None
    if t_col is not None:
        table, t = oldest_first(table, t_col)
    notes = list(table.notes)
    series = []
    for col in cols:
        x, note = numbers(table, col)
        series.append(x)
        notes += [note] if note else []
    if t_col is None or t is None:
        assert ts is not None
        return Signals(series, float(ts), None, None, notes, table)
    ts_grid, series, grid_notes = grid(table.path, table.header[t_col], t, series)
    return Signals(series, ts_grid, t, t_col, notes + grid_notes, table)


def oldest_first(table: Table, t_col: int) -> tuple[Table, Stamps]:
    """``table`` with its rows oldest first, and its time column read (:func:`times`): an
    export written newest first (time going back on every row, never forward) is turned
    round, a note says so, and its times are read again in that order (the date form and
    midnight of times of day are judged in time order); any other order is left for
    :func:`grid` to judge (time going back somewhere is refused)."""
    t = times(table, t_col)
    steps = np.diff(t.seconds)
    if t.seconds.size < 2 or not (np.all(steps <= 0) and np.any(steps < 0)):
        return table, t
    name = table.header[t_col]
    note = (f"rows newest first (column {name!r} from {table.rows[0][t_col].strip()!r} back "
            f"to {table.rows[-1][t_col].strip()!r}): read oldest first")
    table = dataclasses.replace(table, rows=table.rows[::-1], lines=table.lines[::-1],
                                notes=(*table.notes, note))
    return table, times(table, t_col)


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


def times(table: Table, col: int) -> Stamps:
    """Column ``col`` as seconds: numbers as they are, date-times as Unix seconds (in their
    own zone, else ``--tz``, else UTC), with the cells as written for messages."""
    cells = [row[col].strip() if col < len(row) else "" for row in table.rows]
    name = table.header[col]
    where = f"{table.path}: line {{}}, column {name!r}: "
    for i, c in enumerate(cells):
        if not c:
            raise UsageError(where.format(table.lines[i]) + "no time; every row needs one (or "
                             "give --ts S for rows at a fixed interval)")
    if cells and decimals.is_number(cells[0]):  # seconds
        got, how = read_numbers(table, col, cells)
        if not got.text:
            return _numeric_times(table, col, cells, got.values, how)
    if cells and stamps.is_time_of_day(cells[0]):
        of_day = _times_of_day(table, col, cells)
        if of_day is not None:
            return of_day
    try:
        dates = stamps.read_dates(cells, table.tz)
    except stamps.ZoneError as exc:
        raise UsageError(where.format(table.lines[exc.row]) + f"{cells[exc.row]!r}: {exc}"
                         ) from None
    if dates is None:
        i = next((i for i, c in enumerate(cells)
                  if not decimals.is_number(c) and not stamps.is_date(c)), 0)
        folded = [h.casefold() for h in table.header]
        hint = ("; it names a column: a header of other columns where two exports were "
                "appended? Export the tags together, or remove the second header"
                if cells[i].casefold() in folded else "")
        raise UsageError(where.format(table.lines[i]) + f"not a time: {cells[i]!r}{hint}; "
                         f"times may be {stamps.EXAMPLES}; or give --ts S for rows at a fixed "
                         "interval")
    return Stamps(dates.seconds, cells, table.lines, dates.zone,
                  (dates.note,) if dates.note else (), table.appended)


DATE_COLUMNS = ("date", "datum", "fecha", "data", "day")
"""Names (any case) of a column of dates that a column of times of day goes with."""


def _times_of_day(table: Table, col: int, cells: Sequence[str]) -> Stamps | None:
    """A column of times of day (``06:00:00``): read together with the date column beside
    it (:data:`DATE_COLUMNS`, as spreadsheets split a time stamp), else as seconds from the
    first row's midnight, a day added each time the clock passes midnight; said so either
    way. None when the cells are not all times of day."""
    name = table.header[col]
    d_col = next((j for j, h in enumerate(table.header)
                  if j != col and h.strip().casefold() in DATE_COLUMNS), None)
    if d_col is not None:
        joined = [f"{row[d_col].strip()} {c}" if d_col < len(row) else c
                  for row, c in zip(table.rows, cells, strict=True)]
        try:
            dates = stamps.read_dates(joined, table.tz)
        except stamps.ZoneError as exc:
            raise UsageError(f"{table.path}: line {table.lines[exc.row]}, columns "
                             f"{table.header[d_col]!r} and {name!r}: {joined[exc.row]!r}: "
                             f"{exc}") from None
        if dates is not None:
            note = (f"columns {table.header[d_col]!r} and {name!r} read together as the "
                    "time stamp")
            return Stamps(dates.seconds, joined, table.lines, dates.zone,
                          tuple(n for n in (note, dates.note) if n), table.appended)
    secs = stamps.times_of_day(cells)
    if secs is None:
        return None
    note = (f"column {name!r} holds times of day without a date: read as seconds from the "
            "first row's midnight, a day added each time the clock passes midnight (a "
            f"column named {DATE_COLUMNS[0]!r} beside it would be read with it)")
    return Stamps(secs, cells, table.lines, None, (note,), table.appended)


def _numeric_times(table: Table, col: int, cells: Sequence[str], values: np.ndarray,
                   how: str | None) -> Stamps:
    """A time column of numbers: seconds as they are, Unix milliseconds, microseconds or
    nanoseconds read as seconds and said so (:func:`stamps.epoch_unit`); spreadsheet serial
    dates refused, naming them (:func:`stamps.serial_days`), since read as seconds their
    rows would be 1/86400 s apart."""
    notes = [how] if how else []
    name = table.header[col]
    zone: dt.tzinfo | None = None
    unit = stamps.epoch_unit(values)
    if unit is not None:  # shown as date-times (UTC): the file's numbers are not seconds
        zone = dt.UTC
        word, per_second = unit
        values = values / per_second
        first = dt.datetime.fromtimestamp(float(values[0]), dt.UTC)
        notes.append(f"column {name!r} holds Unix time in {word} ({cells[0]!r} is "
                     f"{first:%Y-%m-%d %H:%M:%S} UTC): read as seconds")
    elif stamps.serial_days(values):
        raise UsageError(
            f"{table.path}: column {name!r} holds numbers like {cells[0]!r} (line "
            f"{table.lines[0]}) {float(np.median(np.diff(values))):.3g} apart: spreadsheet "
            f"serial dates (days since 1899-12-30; {cells[0]!r} would be "
            f"{stamps.serial_text(float(values[0]))})? Read as seconds, its rows would be a "
            "fraction of a second apart. Format the column as date-times before saving the "
            "file (e.g. 2024-03-01 06:00:00), or give --ts S for rows at a fixed interval")
    return Stamps(values, cells, table.lines, zone, tuple(notes), table.appended)


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
