"""A long (narrow) export, one row per tag and time, as Wonderware (AVEVA Historian), SQL
queries of most historians and many data lakes write it (``DateTime,TagName,Value``, often
with quality columns), turned into the wide table every command reads: one column per tag,
named by the tag, one row per time (:func:`pivot`). Samples a quality column marks bad
(:mod:`.quality`) become gaps; a tag and time written twice keep the last row."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from . import quality
from ._common import UsageError
from .cells import Cells
from .table import Table, tally
from .timecol import TIME_COLUMNS, times

__all__ = ["TAG_COLUMNS", "VALUE_COLUMNS", "is_long", "pivot"]

TAG_COLUMNS = ("tagname", "tag", "tag name", "tag_name", "name", "pointname", "point",
               "itemid", "item")
"""Names (any case) of a long export's column of tag names."""
VALUE_COLUMNS = ("value", "vvalue", "val")
"""Names (any case) of a long export's column of values."""
MOST_COLUMNS = 12
"""A long export has few columns: the time, the tag, the value and their qualities."""


def _find(header: Sequence[str], names: Sequence[str]) -> int | None:
    folded = [h.strip().casefold() for h in header]
    return next((folded.index(n) for n in names if n in folded), None)


def is_long(header: Sequence[str]) -> bool:
    """Whether the header is a long export's: a time, a tag and a value column among a few."""
    return (len(header) <= MOST_COLUMNS and _find(header, TIME_COLUMNS) is not None
            and _find(header, TAG_COLUMNS) is not None
            and _find(header, VALUE_COLUMNS) is not None)


def pivot(table: Table) -> Table:
    """The long ``table`` as one column per tag (named by the tag, in order of first
    appearance) beside the time column, one row per distinct time, oldest first."""
    t_col = _find(table.header, TIME_COLUMNS)
    tag_col = _find(table.header, TAG_COLUMNS)
    v_col = _find(table.header, VALUE_COLUMNS)
    assert t_col is not None
    assert tag_col is not None
    assert v_col is not None
    if table.size == 0:
        raise UsageError(f"{table.path}: a long export (columns {table.header[t_col]!r}, "
                         f"{table.header[tag_col]!r}, {table.header[v_col]!r}) with no rows")
    seconds = times(table, t_col).seconds
    codes, tags = _codes(table.cells(tag_col))
    values = [c for part in table.cells(v_col).chunks() for c in part]
    notes = [f"a long export (columns {table.header[t_col]!r}, {table.header[tag_col]!r}, "
             f"{table.header[v_col]!r}: one row per tag and time): read as one column per "
             f"tag ({len(tags)}: {', '.join(tags[:6])}{', ...' if len(tags) > 6 else ''})"]
    q = quality.of(table.header, v_col)
    q = q if q is not None else next((j for j, h in enumerate(table.header)
                                      if quality.is_quality(h)), None)
    if q is not None:
        bad, said = quality.bad(table, q)
        if bad.any():
            for i in np.flatnonzero(bad):
                values[i] = ""
            notes.append(f"{int(bad.sum())} rows of bad quality read as gaps ({said})")
    unique, first, inverse = np.unique(seconds, return_index=True, return_inverse=True)
    columns = {0: table.cells(t_col).take(first)}
    named = [k for k, tag in enumerate(tags) if tag]  # a row without a tag is no tag's
    for n, k in enumerate(named):
        col = [""] * unique.size
        for i in np.flatnonzero(codes == k):
            col[inverse[i]] = values[i]
        columns[n + 1] = Cells.of(col)
    return dataclasses.replace(
        table, header=[table.header[t_col], *(tags[k] for k in named)], columns=columns,
        lines=table.lines[first], notes=(*table.notes, *notes), evidence=tally(columns),
        memo={})


def _codes(cells: Cells) -> tuple[np.ndarray, list[str]]:
    """Each row's tag as a number, and the tags in order of first appearance."""
    index: dict[str, int] = {}
    codes = np.empty(len(cells), dtype=np.int64)
    i = 0
    for part in cells.chunks():
        for cell in part:
            codes[i] = index.setdefault(cell.strip(), len(index))
            i += 1
    return codes, list(index)
