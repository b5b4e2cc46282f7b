"""A column of an export's cells, held compactly, for reading a file of any length.

An export is read row by row in chunks of rows (:data:`CHUNK_CELLS` cells at most, so a wide
export's chunk has fewer rows; :mod:`.table`); each column
read keeps its cells as the file wrote them, one string per chunk, the cells joined by line
breaks: the cells' own characters and one more each (a Python list of strings would hold
about 60 bytes more per cell, and the rows' lists more again). Numbers are read from the
chunks one at a time (:mod:`.historian`), so the text of a whole file is never held twice.
A line break inside a cell (a quoted multi-line cell) is held as a space.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

__all__ = ["CHUNK", "CHUNK_CELLS", "Cells"]

CHUNK = 65_536
"""Cells per chunk of a column built in memory (:meth:`Cells.of`, :meth:`Cells.take`)."""
CHUNK_CELLS = 1 << 16
"""Cells of a file's chunk of rows (all its columns): the rows held as lists at once while
reading (about 4 MB of Python strings)."""


class Cells:
    """One column's cells: ``len``, ``cells[i]`` (as written), :meth:`chunks` (lists of
    cells, in order), :meth:`texts` (each chunk's cells joined by ``"\\n"``, for a regular
    expression over the whole chunk)."""

    __slots__ = ("_cache", "_counts", "_starts", "_texts")

    def __init__(self) -> None:
        self._texts: list[str] = []
        self._counts: list[int] = []
        self._starts: list[int] = []
        self._cache: tuple[int, list[str]] = (-1, [])

    @classmethod
    def of(cls, cells: Iterable[str], chunk: int = CHUNK) -> Cells:
        out = cls()
        part: list[str] = []
        for c in cells:
            part.append(c)
            if len(part) == chunk:
                out.add(part)
                part = []
        if part:
            out.add(part)
        return out

    def add(self, cells: Sequence[str], text: str | None = None) -> None:
        """Append ``cells`` (``text``: the same already joined by ``"\\n"``)."""
        if not cells:
            return
        if text is None:
            text = "\n".join(cells)
        if text.count("\n") != len(cells) - 1:  # a cell holds a line break
            text = "\n".join(c.replace("\n", " ") for c in cells)
        self._starts.append(len(self))
        self._texts.append(text)
        self._counts.append(len(cells))

    def __len__(self) -> int:
        return self._starts[-1] + self._counts[-1] if self._texts else 0

    def texts(self) -> Iterator[tuple[int, str]]:
        """``(index of the chunk's first cell, the chunk's cells joined by "\\n")``."""
        yield from zip(self._starts, self._texts, strict=True)

    def chunks(self) -> Iterator[list[str]]:
        for text in self._texts:
            yield text.split("\n")

    def _split(self, k: int, text: str) -> list[str]:
        if self._cache[0] == k:
            return self._cache[1]
        cells = text.split("\n")
        self._cache = (k, cells)
        return cells

    def __getitem__(self, i: int) -> str:
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(i)
        k = bisect.bisect_right(self._starts, i) - 1
        return self._split(k, self._texts[k])[i - self._starts[k]]

    def __iter__(self) -> Iterator[str]:
        for part in self.chunks():
            yield from part

    def reversed(self) -> Cells:
        """The cells in the opposite order."""
        out = Cells()
        for part in reversed(list(self.chunks())):
            out.add(part[::-1])
        return out

    def take(self, index: np.ndarray) -> Cells:
        """The cells at ``index`` (row numbers), in that order."""
        out = Cells()
        for a in range(0, index.size, CHUNK):
            out.add([self[int(i)] for i in index[a:a + CHUNK]])
        return out

    def nbytes(self) -> int:
        """About the memory the cells hold (their text)."""
        return sum(len(t) for t in self._texts)
