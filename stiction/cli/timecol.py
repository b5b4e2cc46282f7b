"""An export's time column read to seconds (:func:`times`): numbers as seconds (Unix
milliseconds to nanoseconds read as such, said so; spreadsheet serial dates refused), ISO
8601 and other common date-times with or without a zone (:mod:`.stamps`, :mod:`.dates`),
times of day with the date column beside them or across midnight; a chunk of rows at a time.
"""

from __future__ import annotations

import datetime as dt
import re

import numpy as np

from . import decimals, stamps
from ._common import UsageError
from .cells import Cells
from .dates import DateColumn, Dates
from .grid import Stamps
from .numeric import read_numbers
from .table import Table

__all__ = ["DATE_COLUMNS", "TIME_COLUMNS", "times"]

TIME_COLUMNS = ("t", "time", "timestamp", "t_stamp", "datetime", "date time", "date")
"""Column names taken for the time when ``--time`` is not given (any case), in this order
(``t_stamp``: Ignition's); else the first column without a name (PI DataLink's)."""
DATE_COLUMNS = ("date", "datum", "fecha", "data", "day")
"""Names (any case) of a column of dates that a column of times of day goes with."""
_EMPTY = re.compile(r"^[^\S\n]*$", re.M)


def times(table: Table, col: int) -> Stamps:
    """Column ``col`` as seconds: numbers as they are, date-times as Unix seconds (in their
    own zone, else ``--tz``, else UTC), with the cells as written for messages."""
    cells = table.cells(col)
    name = table.header[col]
    where = f"{table.path}: line {{}}, column {name!r}: "
    for start, text in cells.texts():
        empty = _EMPTY.search(text)
        if empty is not None:
            i = start + text.count("\n", 0, empty.start())
            raise UsageError(where.format(table.lines[i]) + "no time; every row needs one (or "
                             "give --ts S for rows at a fixed interval)")
    notes = () if name else (f"column {col + 1} has no name (as PI DataLink leaves the time "
                             "column's): read as the time",)
    first = cells[0].strip() if len(cells) else ""
    if decimals.is_number(first):  # seconds
        got, how = read_numbers(table, col)
        if not got.text:
            return _numeric_times(table, col, got.values, how, notes)
    if stamps.is_time_of_day(first):
        of_day = _times_of_day(table, col)
        if of_day is not None:
            return of_day
    dates = _dates(table, cells, f"column {name!r}")
    if dates is None:
        i, cell = next(((i, c.strip()) for i, c in enumerate(cells)
                        if not decimals.is_number(c.strip()) and not stamps.is_date(c.strip())),
                       (0, first))
        folded = [h.casefold() for h in table.header]
        hint = ("; it names a column: a header of other columns where two exports were "
                "appended? Export the tags together, or remove the second header"
                if cell.casefold() in folded else "")
        raise UsageError(where.format(table.lines[i]) + f"not a time: {cell!r}{hint}; "
                         f"times may be {stamps.EXAMPLES}; or give --ts S for rows at a fixed "
                         "interval")
    return Stamps(dates.seconds, cells, table.lines, dates.zone,
                  (*notes, *((dates.note,) if dates.note else ())), table.appended,
                  dates.naive)


def _dates(table: Table, cells: Cells, what: str) -> Dates | None:
    """The cells (stripped) read as date-times (:class:`~.dates.DateColumn`); a zone that
    needs ``--tz`` a usage error naming it."""
    column = DateColumn(table.tz)
    try:
        for part in cells.chunks():
            column.add([c.strip() for c in part])
    except stamps.ZoneError as exc:
        raise UsageError(f"{table.path}: line {table.lines[exc.row]}, {what}: "
                         f"{cells[exc.row].strip()!r}: {exc}") from None
    return column.result()


def _times_of_day(table: Table, col: int) -> Stamps | None:
    """A column of times of day (``06:00:00``): read together with the date column beside
    it (:data:`DATE_COLUMNS`, as spreadsheets split a time stamp), else as seconds from the
    first row's midnight, a day added each time the clock passes midnight; said so either
    way. None when the cells are not all times of day."""
    name = table.header[col]
    cells = table.cells(col)
    d_col = next((j for j, h in enumerate(table.header)
                  if j != col and h.strip().casefold() in DATE_COLUMNS and j in table.columns),
                 None)
    if d_col is not None:
        joined = Cells()
        for day, part in zip(table.cells(d_col).chunks(), cells.chunks(), strict=True):
            joined.add([f"{d.strip()} {c.strip()}" for d, c in zip(day, part, strict=True)])
        dates = _dates(table, joined, f"columns {table.header[d_col]!r} and {name!r}")
        if dates is not None:
            note = (f"columns {table.header[d_col]!r} and {name!r} read together as the "
                    "time stamp")
            return Stamps(dates.seconds, joined, table.lines, dates.zone,
                          tuple(n for n in (note, dates.note) if n), table.appended,
                          dates.naive)
    secs = np.empty(len(cells))
    state = (0.0, -np.inf)
    for start, part in zip((s for s, _ in cells.texts()), cells.chunks(), strict=True):
        got = stamps.times_of_day(part, state)
        if got is None:
            return None
        secs[start:start + len(part)], state = got
    note = (f"column {name!r} holds times of day without a date: read as seconds from the "
            "first row's midnight, a day added each time the clock passes midnight (a "
            f"column named {DATE_COLUMNS[0]!r} beside it would be read with it)")
    return Stamps(secs, cells, table.lines, None, (note,), table.appended)


def _numeric_times(table: Table, col: int, values: np.ndarray, how: str | None,
                   notes: tuple[str, ...]) -> Stamps:
    """A time column of numbers: seconds as they are, Unix milliseconds, microseconds or
    nanoseconds read as seconds and said so (:func:`stamps.epoch_unit`); spreadsheet serial
    dates refused, naming them (:func:`stamps.serial_days`), since read as seconds their
    rows would be 1/86400 s apart."""
    said = [*notes, *([how] if how else [])]
    name = table.header[col]
    first_cell = table.cell(0, col)
    zone: dt.tzinfo | None = None
    unit = stamps.epoch_unit(values)
    if unit is not None:  # shown as date-times (UTC): the file's numbers are not seconds
        zone = dt.UTC
        word, per_second = unit
        values = values / per_second
        first = dt.datetime.fromtimestamp(float(values[0]), dt.UTC)
        said.append(f"column {name!r} holds Unix time in {word} ({first_cell!r} is "
                    f"{first:%Y-%m-%d %H:%M:%S} UTC): read as seconds")
    elif stamps.serial_days(values):
        raise UsageError(
            f"{table.path}: column {name!r} holds numbers like {first_cell!r} (line "
            f"{table.lines[0]}) {float(np.median(np.diff(values))):.3g} apart: spreadsheet "
            f"serial dates (days since 1899-12-30; {first_cell!r} would be "
            f"{stamps.serial_text(float(values[0]))})? Read as seconds, its rows would be a "
            "fraction of a second apart. Format the column as date-times before saving the "
            "file (e.g. 2024-03-01 06:00:00), or give --ts S for rows at a fixed interval")
    return Stamps(values, table.cells(col), table.lines, zone, tuple(said), table.appended)
