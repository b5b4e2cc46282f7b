"""Which mark is the decimal one in a historian's column of numbers, from the column's
evidence, never by guess.

Historians export numbers as the exporting PC's locale writes them: ``1,118.5`` (English:
``.`` the decimal mark, ``,`` grouping thousands) or ``1.118,5`` (German, Italian, ...:
the other way round), sometimes with spaces or apostrophes grouping thousands (``1 118,5``,
``1'118.5``). Most cells tell which by themselves (``45.3``, ``0,25``, ``1,118.5``); a cell
like ``1,118`` or ``1.118`` does not: it reads as 1118 or as 1.118. :func:`tally` gathers a
column's evidence, :func:`decide` gives the decimal mark it allows, or raises
:class:`Ambiguous` / :class:`Mixed` when it allows none or two, for the caller to say so
instead of picking one; :func:`value` reads a cell with the mark decided.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import re
from collections.abc import Iterable, Sequence

import numpy as np

__all__ = ["COMMA", "POINT", "Ambiguous", "Column", "Mixed", "both_readings", "decide",
           "grouped", "is_number", "kind", "read_column", "read_text_chunk", "tally",
           "tally_text", "value"]

POINT, COMMA = ".", ","
BOTH = "both"
_EXP = r"(?:[eE][-+]?\d+)?"
_READINGS = {
    # the decimal mark -> a number written with it: thousands grouped by the other mark
    # (the leading group 1-3 digits, not starting with 0) with an optional fraction, or
    # digits with an optional fraction and exponent
    POINT: re.compile(rf"[-+]?(?:[1-9]\d{{0,2}}(?:,\d{{3}})+(?:\.\d*)?|(?:\d+\.?\d*|\.\d+){_EXP})"),
    COMMA: re.compile(rf"[-+]?(?:[1-9]\d{{0,2}}(?:\.\d{{3}})+(?:,\d*)?|(?:\d+,?\d*|,\d+){_EXP})"),
}
_OTHER = {POINT: COMMA, COMMA: POINT}
_INT_GROUPS = {POINT: re.compile(r"[-+]?[1-9]\d{0,2}(?:\.\d{3})+"),
               COMMA: re.compile(r"[-+]?[1-9]\d{0,2}(?:,\d{3})+")}
"""A cell with one mark only that also reads with the other as decimal: ``1.118``, ``1,118``."""
_SPACED = re.compile(r"[-+]?[1-9]\d{0,2}(?:[ '\u00a0\u202f\u2009]\d{3})+(?:[.,]\d*)?")
"""Thousands grouped by a space, a no-break or thin space or an apostrophe: never decimal."""
_SEPARATORS = " '\u00a0\u202f\u2009"
_SPACES = str.maketrans("", "", _SEPARATORS)
_WORDS = {"nan", "inf", "+inf", "-inf", "infinity", "+infinity", "-infinity"}


def value(cell: str, mark: str) -> float | None:
    """The cell as a number with ``mark`` (``.`` or ``,``) the decimal mark, NaN when empty,
    None when it is text (or a number only with the other mark)."""
    c = cell.strip()
    other = _OTHER[mark]
    if other not in c and "_" not in c:  # the common case: no grouping, one float()
        try:
            return float(c if mark == POINT else c.replace(",", "."))
        except ValueError:
            pass
    if not c:
        return math.nan
    if c.casefold() in _WORDS:
        return float(c)
    if _SPACED.fullmatch(c):
        c = c.translate(_SPACES)
    if _READINGS[mark].fullmatch(c) is None:
        return None
    return float(c.replace(other, "").replace(",", "."))


def is_number(cell: str) -> bool:
    """Whether the cell is a number with either mark."""
    return value(cell, POINT) is not None or value(cell, COMMA) is not None


def grouped(cell: str, mark: str) -> bool:
    """Whether the cell, a number with ``mark`` the decimal mark, groups its thousands."""
    if _OTHER[mark] in cell:
        return True
    return any(s in cell for s in _SEPARATORS) and _SPACED.fullmatch(cell.strip()) is not None


@dataclasses.dataclass
class Column:
    """A column read with one decimal mark (:func:`read_column`)."""

    values: np.ndarray
    """The numbers, NaN for empty cells and text."""
    text: collections.Counter[str]
    """Text cell (stripped) -> how many."""
    grouped: int | None
    """The index of the first cell that groups thousands, if any."""
    other: int | None
    """The index of the first cell that is a number only with the other mark, if any."""


def read_column(cells: Sequence[str], mark: str) -> Column:
    """Every cell read with ``mark`` the decimal mark (:func:`value`)."""
    out = np.empty(len(cells))
    text: collections.Counter[str] = collections.Counter()
    first_grouped = first_other = None
    other = _OTHER[mark]
    for i, cell in enumerate(cells):
        if other not in cell and "_" not in cell:  # the common case, as in value()
            try:
                out[i] = float(cell if mark == POINT else cell.replace(",", "."))
                continue
            except ValueError:
                pass
        x = value(cell, mark)
        if x is None:
            if first_other is None and value(cell, other) is not None:
                first_other = i
            text[cell.strip()] += 1
            x = math.nan
        elif first_grouped is None and grouped(cell, mark):
            first_grouped = i
        out[i] = x
    return Column(out, text, first_grouped, first_other)


def kind(cell: str) -> str | None:
    """``"."`` or ``","`` for a cell that is a number with this decimal mark only,
    ``"both"`` for one that reads as two different numbers (``1,118``: 1118 or 1.118),
    None for text or a number that reads the same either way (``12``, ``1e5``, empty)."""
    for mark in (POINT, COMMA):
        other = _OTHER[mark]
        if other not in cell:  # one kind of mark at most: the cell is a number with it, or
            if mark not in cell:  # a number with the other mark only if grouped by this one
                continue
            if value(cell, mark) is None:
                return other if value(cell, other) is not None else None
            return BOTH if _INT_GROUPS[mark].fullmatch(cell.strip()) else mark
    if "." not in cell and "," not in cell:
        return None
    point, comma = value(cell, POINT), value(cell, COMMA)
    if point is None:
        return None if comma is None else COMMA
    return POINT if comma is None else BOTH


_BOTH_CELL = re.compile(r"^[^\S\n]*[-+]?[1-9]\d{0,2}[.,]\d{3}[^\S\n]*$", re.M)
"""A cell that reads as two numbers (``1,118``, ``50.125``): :func:`kind` ``"both"``."""
_TELLING = re.compile(r"^(?![^\S\n]*[-+]?[1-9]\d{0,2}[.,]\d{3}[^\S\n]*$)"
                      r"[^\n:/A-DF-Za-df-z]*[.,][^\n:/A-DF-Za-df-z]*$", re.M)
"""A cell with a decimal mark that may tell which one is the decimal mark: not of the form
that reads two ways, and without a letter (but the exponent's e), a colon or a slash, which
no number has."""


def tally_text(text: str, start: int, first: dict[str, int]) -> bool:
    """:func:`tally` (``decisive``) of a chunk of cells joined by ``"\n"`` whose first cell
    is cell ``start`` of the column, into ``first`` (the column's evidence so far); whether
    the column is now decided (a cell needs ``.`` or ``,``). Regular expressions over the
    whole chunk find the cells that matter, so a column of a million cells that all read
    two ways is tallied in C, not cell by cell."""
    if POINT in first or COMMA in first:
        return True
    end, pos, found = len(text), 0, None
    while (m := _TELLING.search(text, pos)) is not None:
        k = kind(m.group())
        if k is not None and k != BOTH:
            end, found = m.start(), k
            break
        if k == BOTH and BOTH not in first:
            first[BOTH] = start + text.count("\n", 0, m.start())
        pos = m.end() + 1
    if BOTH not in first or first[BOTH] >= start:
        b = _BOTH_CELL.search(text, 0, end)
        if b is not None:
            at = start + text.count("\n", 0, b.start())
            first[BOTH] = min(first.get(BOTH, at), at)
    if found is None:
        return False
    first[found] = start + text.count("\n", 0, end)
    return True


def read_text_chunk(cells: Sequence[str], text: str, mark: str) -> Column:
    """:func:`read_column` of a chunk (``text``: the cells joined by ``"\n"``): every cell at
    once where no cell needs more than ``float`` (the common case: no thousands grouped, no
    text), else cell by cell."""
    other = _OTHER[mark]
    if "_" not in text and other not in text:
        plain = cells if mark == POINT else text.replace(",", ".").split("\n")
        try:
            return Column(np.fromiter(map(float, plain), float, len(cells)),
                          collections.Counter(), None, None)
        except ValueError:
            pass
    return read_column(cells, mark)


def both_readings(text: str) -> tuple[list[float], list[float]]:
    """The cells of a chunk that read two ways (``1.118``, ``44,000``), each read with its
    mark as the decimal mark: those written with ``.`` and those written with ``,``. Read
    with the mark as a thousands separator each is 1000 times as large."""
    cells = [c.strip() for c in _BOTH_CELL.findall(text)]
    return ([float(c) for c in cells if "." in c],
            [float(c.replace(",", ".")) for c in cells if "," in c])


def tally(cells: Iterable[str], *, decisive: bool = False) -> dict[str, int]:
    """A column's evidence: kind (:func:`kind`) -> the index of its first cell;
    ``decisive``: stop at the first cell that needs one mark."""
    first: dict[str, int] = {}
    seen: set[str] = set()
    for i, c in enumerate(cells):
        if ("." not in c and "," not in c) or c in seen:
            continue
        seen.add(c)
        k = kind(c)
        if k is not None and k not in first:
            first[k] = i
            if decisive and k != BOTH:
                break
    return first


class Ambiguous(Exception):
    """Every cell that could tell reads two ways (``row``: the index of the first)."""

    def __init__(self, row: int) -> None:
        super().__init__(row)
        self.row = row


class Mixed(Exception):
    """Some cells need ``.`` as the decimal mark, others ``,`` (the first of each)."""

    def __init__(self, point_row: int, comma_row: int) -> None:
        super().__init__(point_row, comma_row)
        self.point_row, self.comma_row = point_row, comma_row


def decide(own: dict[str, int], others: Sequence[dict[str, int]] = (),
           usual: str | None = None) -> tuple[str, str | None]:
    """The decimal mark of a column from its own evidence (:func:`tally`), else from the
    other columns of the same export (one export, one locale), else ``usual`` (the mark
    the file's layout implies, if any); and which settled it when the column could not:
    ``"others"`` or ``"usual"``, else None.

    Raises :class:`Mixed` when the column holds both styles, :class:`Ambiguous` when its
    cells read two ways and nothing else settles it (no other column tells, or they
    disagree, and no ``usual``)."""
    if POINT in own and COMMA in own:
        raise Mixed(own[POINT], own[COMMA])
    for mark in (POINT, COMMA):
        if mark in own:
            return mark, None
    if BOTH not in own:
        return POINT, None  # every cell reads the same either way
    marks = {m for t in others for m in t if m != BOTH}
    if len(marks) == 1:
        return marks.pop(), "others"
    if usual is not None and not marks:
        return usual, "usual"
    raise Ambiguous(own[BOTH])
