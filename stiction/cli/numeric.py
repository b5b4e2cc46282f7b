"""A column of an export read as numbers (:func:`numbers`): its decimal mark decided from its
own cells, else the file's other columns, else an OP column's range (:func:`read_numbers`),
text cells and samples of bad quality as gaps, with the note that says how.

One export, one locale: a column whose every number reads two ways (``1,118``: 1118 or 1.118;
``44.000``: 44 or 44000) takes the mark the file's other columns show (:mod:`.decimals`),
``.`` in a ``,``-separated file, else the one under which a controller output's numbers lie
inside its range (0-100 % where none is given) when read the other way they lie a thousand
times outside it; else it is refused, naming both readings. Columns are read a chunk at a
time (:mod:`.cells`): each number costs 8 bytes, the text is not copied."""

from __future__ import annotations

import collections
import re

import numpy as np

from . import decimals, quality
from ._common import UsageError
from .table import Table

__all__ = ["OP_RANGE", "numbers", "read_numbers", "summarised"]

OP_RANGE = (0.0, 100.0)
"""A controller output's range where none is given: percent."""
_OP_NAME = re.compile(r"(?:^|[._ /:\]])(?:op|mv|out|output)$", re.IGNORECASE)
"""The name of a controller output column (``op``, ``FIC101.OP``, ``TAG_MV``, ``TAG OUT``)."""


def _spans(table: Table) -> dict[int, tuple[float, float]]:
    """The controller output columns of the table and their ranges: those the command named
    (``--op``), else those whose name says so (``op``, ``TAG.OP``, ``TAG_MV``, ...)."""
    given = table.memo.get("spans")
    if isinstance(given, dict) and given:
        return given
    return {j: OP_RANGE for j, h in enumerate(table.header)
            if j in table.columns and _OP_NAME.search(h.strip())}


def _by_range(table: Table, col: int) -> str | None:
    """The decimal mark an OP column's numbers that read two ways take from its range: the
    one under which all of them lie inside it (widened by a tenth of the span each side)
    while read the other way (a thousand times as large) some lie outside; None when
    neither or both do."""
    lo, hi = _spans(table)[col]
    wide = (lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))
    point: list[float] = []
    comma: list[float] = []
    for _, text in table.cells(col).texts():
        p, c = decimals.both_readings(text)
        point += p
        comma += c
    fits = {}
    for mark, own, other in ((".", point, comma), (",", comma, point)):
        values = np.array(own + [1000.0 * x for x in other])
        fits[mark] = bool(values.size) and bool(np.all((values >= wide[0]) & (values <= wide[1])))
    ok = [m for m, f in fits.items() if f]
    return ok[0] if len(ok) == 1 else None


def _range_mark(table: Table) -> tuple[str, int] | None:
    """The decimal mark the export's OP columns settle by their range (:func:`_by_range`),
    where those that settle one agree, with the first such column; worked out once."""
    if "range" not in table.memo:
        got = {j: m for j in _spans(table) if (m := _by_range(table, j)) is not None}
        marks = set(got.values())
        table.memo["range"] = (marks.pop(), min(got)) if len(marks) == 1 else None
    found = table.memo["range"]
    return found if isinstance(found, tuple) else None


def read_numbers(table: Table, col: int) -> tuple[decimals.Column, str | None]:
    """Column ``col``'s cells as numbers with its decimal mark (the one given, else the one
    its cells show, else the one the other columns show, :func:`decimals.decide`, else the
    one an OP column's range shows, :func:`_by_range`), and the note that says how they
    were read when it is not plain: thousands grouped, or the mark taken from elsewhere. A
    column that reads two ways, or holds both styles, is refused."""
    own = dict(table.evidence.get(col, {}))
    others = [table.evidence.get(j, {}) for j in range(len(table.header)) if j != col]
    usual = "." if table.delimiter == "," else None  # a CSV proper: decimal points
    settled: str | None
    try:
        mark, settled = (table.decimal, "given") if table.decimal is not None else \
            decimals.decide(own, others, usual)
    except decimals.Ambiguous as exc:
        by_range = _range_mark(table)
        if by_range is None:
            raise UsageError(_ambiguous(table, col, exc.row)) from None
        mark, settled = by_range[0], "range"
    got = _read_cells(table, col, mark)
    if got.other is not None and settled is None:
        first = own[mark]
        point, comma = (first, got.other) if mark == "." else (got.other, first)
        raise UsageError(
            f"{table.path}: column {table.header[col]!r} mixes decimal marks: "
            f"{table.cell(point, col)!r} (line {table.lines[point]}) has a decimal point, "
            f"{table.cell(comma, col)!r} (line {table.lines[comma]}) a decimal comma; give "
            "--decimal . or --decimal , (cells of the other style become gaps, counted)")
    return got, _how(table, col, mark, settled, got)


def _how(table: Table, col: int, mark: str, settled: str | None, got: decimals.Column
         ) -> str | None:
    """The note of how column ``col`` was read (:func:`read_numbers`), or None."""
    name = table.header[col]
    own = table.evidence.get(col, {})
    cell = table.cell(own[decimals.BOTH], col) if decimals.BOTH in own else ""
    read = f"column {name!r}: {cell!r} read as {decimals.value(cell, mark):.10g}: "
    if settled == "range":
        by = _range_mark(table)
        assert by is not None
        j = by[1]
        lo, hi = _spans(table)[j]
        if j == col:
            return read + (f"read with {mark!r} grouping thousands it would be "
                           f"{decimals.value(cell, ',' if mark == '.' else '.'):.10g}, "
                           f"outside the OP range {lo:g}-{hi:g} (give --decimal "
                           f"{',' if mark == '.' else '.'} if that is the decimal mark)")
        return read + (f"{mark!r} is the decimal mark of this export (column "
                       f"{table.header[j]!r} reads inside its OP range {lo:g}-{hi:g} only so)")
    if settled == "others":
        j = next(j for j in range(len(table.header))
                 if j != col and mark in table.evidence.get(j, {}))
        return read + (f"{mark!r} is the decimal mark of this export (column "
                       f"{table.header[j]!r}: {_example(table, j, mark)!r})")
    if settled == "usual" and decimals.grouped(cell, mark):
        return read + "'.' is the decimal mark of a ','-separated file (give --decimal , " \
            "if ',' is)"
    if got.grouped is None:
        return None
    example = table.cell(got.grouped, col)
    other = "," if mark == "." else "."
    sep = f"{other!r}" if other in example else "a space"
    return (f"column {name!r}: thousands grouped ({example!r} read as "
            f"{decimals.value(example, mark):.10g}: {sep} groups thousands, {mark!r} is "
            "the decimal mark)")


def _example(table: Table, j: int, mark: str) -> str:
    """Column ``j``'s cell that shows ``mark``: from the column if it was read, else the
    line it is on."""
    i = table.evidence[j][mark]
    return table.cell(i, j) if j in table.columns else f"line {table.lines[i]}"


def _read_cells(table: Table, col: int, mark: str) -> decimals.Column:
    """Every cell of the column read with ``mark``, chunk by chunk (:func:`decimals.
    read_text_chunk`): the numbers, the texts counted, the first grouped cell and the first
    cell that is a number only with the other mark."""
    cells = table.cells(col)
    values = np.empty(len(cells))
    text: collections.Counter[str] = collections.Counter()
    grouped = other = None
    for (start, joined), part in zip(cells.texts(), cells.chunks(), strict=True):
        got = decimals.read_text_chunk(part, joined, mark)
        values[start:start + len(part)] = got.values
        text.update(got.text)
        grouped = grouped if grouped is not None or got.grouped is None else start + got.grouped
        other = other if other is not None or got.other is None else start + got.other
    return decimals.Column(values, text, grouped, other)


def _ambiguous(table: Table, col: int, row: int) -> str:
    cell = table.cell(row, col)
    p, c = decimals.value(cell, "."), decimals.value(cell, ",")
    sep = "," if "," in cell else "."
    grouping, decimal = f"{sep!r} grouping thousands", f"{sep!r} the decimal mark"
    first, second = (f"{p:.10g} with {grouping}", f"{c:.10g} with {decimal}") if sep == "," \
        else (f"{p:.10g} with {decimal}", f"{c:.10g} with {grouping}")
    return (f"{table.path}: column {table.header[col]!r}: {cell!r} (line {table.lines[row]}) "
            f"reads as {first} or as {second}, and no number in the file tells which; give "
            f"--decimal . (reads {p:.10g}) or --decimal , (reads {c:.10g})")


def numbers(table: Table, col: int) -> tuple[np.ndarray, str | None]:
    """Column ``col`` as numbers, text cells and samples its quality column marks bad
    (:func:`.quality.bad`) as gaps (NaN), and the note that counts them and says how the
    numbers were read when they group thousands (:func:`read_numbers`)."""
    got, how = read_numbers(table, col)
    text = got.text
    name = table.header[col]
    if text and not np.isfinite(got.values).any():
        first = next(iter(text))
        raise UsageError(f"{table.path}: column {name!r} holds no numbers (e.g. {first!r}); "
                         "is it the right column? Give --op/--pv COL")
    notes = [how] if how else []
    if text:
        kinds = ", ".join(f"{k!r} {n}" for k, n in text.most_common(3))
        more = "" if len(text) <= 3 else f" and {len(text) - 3} other texts"
        notes.append(f"column {name!r}: {sum(text.values())} text cells treated as gaps: "
                     f"{kinds}{more}")
    values = got.values
    q = quality.of(table.header, col)
    if q is not None and q in table.columns:
        bad, said = quality.bad(table, q)
        hit = bad & np.isfinite(values)
        if hit.any():
            values = np.where(bad, np.nan, values)
            notes.append(f"column {name!r}: {int(hit.sum())} samples of bad quality treated "
                         f"as gaps ({said})")
    return values, "; ".join(notes) or None




_READ_AS = re.compile(r"^column (?P<name>'.*?'): (?P<cell>'.*?') read as (?P<value>\S+): "
                      r"(?P<why>.*)$")
SHOWN = 3
"""Columns named in full where several were read the same way (:func:`summarised`)."""


def summarised(notes: list[str]) -> list[str]:
    """The notes, those that say several columns were read the same way (the decimal mark
    taken from elsewhere: a wide export of 500 columns of ``52.989`` would say it 500
    times) said once, naming the first :data:`SHOWN` columns and counting the others."""
    groups: dict[str, list[re.Match[str]]] = {}
    for n in notes:
        m = _READ_AS.match(n)
        if m is not None:
            groups.setdefault(m["why"], []).append(m)
    out = []
    said: set[str] = set()
    for n in notes:
        m = _READ_AS.match(n)
        if m is None or len(groups[m["why"]]) <= SHOWN:
            out.append(n)
            continue
        if m["why"] in said:
            continue  # said with the first of its group
        said.add(m["why"])
        same = groups[m["why"]]
        shown = ", ".join(f"{g['name']} ({g['cell']} read as {g['value']})"
                          for g in same[:SHOWN])
        out.append(f"{len(same)} columns read so: {shown} and {len(same) - SHOWN} more: "
                   f"{m['why']}")
    return out
