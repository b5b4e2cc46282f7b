"""Reading a window as process historians export it, for ``stiction analyze``.

A historian's CSV export is read as it is: the file into a table by :mod:`.table` (the
delimiter sniffed, the encoding, a preamble, units rows and repeated headers; streamed, only
the columns needed kept), a long export of one row per tag and time (``DateTime, TagName,
Value``) turned into one column per tag (:mod:`.narrow`), decimal commas and thousands
separators (``1,118.5`` or ``1.118,5``: the decimal mark decided per column from the whole
column's evidence, :mod:`.decimals`, else from the file's other columns, else from an OP
column that reads inside its OP range one way only; a column that still reads two ways is
refused, naming both readings), column names matched without regard to case, time stamps
read by :mod:`.timecol`, rows written newest first turned round (said so), text cells in OP
or PV ("I/O Timeout", "Shutdown", "Bad") and samples a quality column marks bad
(:mod:`.quality`) as gaps, counted. Rows go on a grid of the median sample time
(:mod:`.grid`); time stamps that wander off it are refused. Every problem is a
:class:`~stiction.cli._common.UsageError` that names the file, the line or column, and what
to do.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from . import narrow, quality
from ._common import UsageError
from .cells import Cells
from .grid import Stamps, grid, on_grid
from .numeric import OP_RANGE, numbers, read_numbers, summarised
from .quality import is_quality
from .table import Select, Table, add_reading_options
from .table import read_table as _read_table
from .timecol import DATE_COLUMNS, TIME_COLUMNS, times

__all__ = ["DATE_COLUMNS", "OP_RANGE", "TIME_COLUMNS", "Cells", "Stamps", "Table",
           "add_reading_options", "column", "grid", "is_quality", "needed", "numbers",
           "oldest_first", "on_grid", "read_numbers", "read_signals", "read_table",
           "summarised", "time_choice", "times", "write_export"]



def read_table(path: Path, *, decimal: str | None = None, tz: dt.tzinfo | None = None,
               select: Select | None = None) -> Table:
    """:func:`.table.read_table`, and a long export turned wide (:func:`.narrow.pivot`,
    every tag's column kept): one whose header is a long export's (:func:`.narrow.is_long`)
    and does not hold the columns asked for."""
    long = []

    def pick(header: list[str]) -> Iterable[int]:
        try:
            if select is not None:
                return select(header)
            if not narrow.is_long(header):
                return range(len(header))
        except UsageError:
            if not narrow.is_long(header):
                raise
        long.append(True)
        return range(len(header))

    table = _read_table(path, decimal=decimal, tz=tz, select=pick)
    return narrow.pivot(table) if long else table


def column(table: Table | tuple[Path, list[str]], name: str, option: str) -> int:
    """The index of column ``name``: its exact name, else its name in any case."""
    path, header = (table.path, table.header) if isinstance(table, Table) else table
    if name in header:
        return header.index(name)
    same = [i for i, h in enumerate(header) if h.casefold() == name.casefold()]
    if len(same) == 1:
        return same[0]
    if same:
        raise UsageError(f"{path}: columns {', '.join(repr(header[i]) for i in same)} differ "
                         f"only in case; give {option} with the exact name")
    raise UsageError(f"{path}: no column {name!r} (columns: {', '.join(header)}); give "
                     f"{option} COL with one of them")


def time_column(header: Sequence[str]) -> int | None:
    """The first of :data:`TIME_COLUMNS` the header has (any case), else the first column
    without a name (PI DataLink leaves the time's empty), or None."""
    folded = [h.casefold() for h in header]
    named = next((folded.index(n) for n in TIME_COLUMNS if n in folded), None)
    return named if named is not None else next((i for i, h in enumerate(header) if not h),
                                                None)


def time_choice(table: Table | tuple[Path, list[str]], time: str | None, ts: float | None
                ) -> int | None:
    """The time column a command reads: ``--time COL`` where given, else with no ``--ts``
    :func:`time_column` (none: a usage error naming the columns), else None (rows every
    ``--ts`` seconds)."""
    path, header = (table.path, table.header) if isinstance(table, Table) else table
    if time is not None:
        return column((path, header), time, "--time")
    if ts is not None:
        return None
    t_col = time_column(header)
    if t_col is None:
        raise UsageError(f"{path}: no time column 't' (columns: {', '.join(header)}); give "
                         "--time COL or --ts S")
    return t_col


def needed(header: list[str], path: Path, columns: Sequence[tuple[str, str]],
           time: str | None, ts: float | None) -> list[int]:
    """The columns to keep of a file to read ``columns`` from (:func:`read_signals`): those,
    the time column (and a date column a time of day may go with) and their quality
    columns (:func:`.quality.of`)."""
    keep = [column((path, header), name, option) for name, option in columns]
    t_col = time_choice((path, header), time, ts)
    keep += [] if t_col is None else [t_col]
    keep += [j for j, h in enumerate(header) if h.strip().casefold() in DATE_COLUMNS]
    return keep + [q for j in keep if (q := quality.of(header, j)) is not None]


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
                 ts: float | None, op_range: tuple[float, float] | None = None) -> Signals:
    """The ``(name, option)`` columns of ``table`` as numbers (the one of ``--op`` read with
    ``op_range``, default :data:`OP_RANGE`, to tell its decimal mark where its numbers do
    not), the time column chosen by :func:`time_choice`, at least two rows, put on the grid
    of the median sample time (:func:`grid`) where the file has times."""
    cols = [column(table, name, option) for name, option in columns]
    spans = {c: op_range or OP_RANGE for c, (_, option) in zip(cols, columns, strict=True)
             if option == "--op"}
    table = dataclasses.replace(table, memo={"spans": spans})
    t_col = time_choice(table, time, ts)
    if table.size < 2:
        raise UsageError(f"{table.path}: {table.size} samples, need at least 2")
    t = None
    if t_col is not None:
        table, t = oldest_first(table, t_col)
    notes = list(table.notes)
    series = []
    for col in cols:
        x, note = numbers(table, col)
        series.append(x)
        notes += [note] if note else []
    # the numbers read, their text goes: only the time column's stays, for messages
    table = dataclasses.replace(table, columns={j: c for j, c in table.columns.items()
                                                if j == t_col})
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
    note = (f"rows newest first (column {name!r} from {table.cell(0, t_col)!r} back "
            f"to {table.cell(-1, t_col)!r}): read oldest first")
    table = dataclasses.replace(table.reversed(), notes=(*table.notes, note))
    return table, times(table, t_col)


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
