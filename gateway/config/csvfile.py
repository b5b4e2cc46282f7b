"""A spreadsheet's CSV file as a crew saves it, read into records with their line numbers
(the findings file, :mod:`gateway.config.findings`).

What spreadsheets write and a line-by-line reader got wrong (issue 35 item 8):

* **text** in UTF-8 (a byte-order mark ignored), UTF-16 with its byte-order mark (Excel's
  "Unicode text"), or Windows-1252 (Excel's "CSV" on a Western European Windows: ``Müller``
  is the byte ``0xFC``): :func:`decode` reads each line as UTF-8 where it is, else as
  Windows-1252, and names the line of a byte that is neither;
* a **cell over several lines** (Alt+Enter in Excel: a line break inside a quoted cell) is
  one cell of one record, numbered by the line it starts on;
* a first line ``sep=;`` (Excel's hint to itself, written by many exports) names the
  delimiter and is no header;
* empty lines, and lines starting with ``#`` between records, are skipped.
"""

from __future__ import annotations

import codecs
import csv
import re
from collections.abc import Iterator

__all__ = ["DELIMITERS", "DecodeError", "decode", "records"]

DELIMITERS = ",;\t"
_SEP = re.compile(r'\s*"?sep=(.)"?\s*', re.I)


class DecodeError(ValueError):
    """Bytes that are no text: ``line`` (from 1) of the first one."""

    def __init__(self, line: int) -> None:
        super().__init__(f"line {line}")
        self.line = line


def decode(data: bytes) -> str:
    """The text of ``data`` (see the module docstring); DecodeError naming the first line
    that is neither UTF-8 nor Windows-1252."""
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise DecodeError(data[:exc.start].count(b"\n") + 1) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        pass
    lines = data.removeprefix(codecs.BOM_UTF8).split(b"\n")
    out = []
    for n, line in enumerate(lines, start=1):
        try:
            out.append(line.decode("utf-8"))
        except UnicodeDecodeError:
            try:
                out.append(line.decode("cp1252"))
            except UnicodeDecodeError:
                raise DecodeError(n) from None
    return "\n".join(out)


def records(text: str) -> tuple[str, Iterator[tuple[int, list[str]]]]:
    """The delimiter of ``text`` and ``(line, cells)`` of each of its records, the header
    first: ``line`` is where the record starts (from 1). The delimiter is the ``sep=``
    line's, else the one of :data:`DELIMITERS` the header holds most of."""
    lines = [line + "\n" for line in text.split("\n")]  # csv's own line ends only
    k = _first(lines, 0)
    sep = _SEP.fullmatch(lines[k].rstrip("\r\n")) if k < len(lines) else None
    if sep is not None:
        k = _first(lines, k + 1)
    if k == len(lines):
        return ",", iter(())
    delimiter = sep.group(1) if sep is not None else max(DELIMITERS, key=lines[k].count)
    return delimiter, _records(_Feed(lines, k), delimiter)


def _records(feed: _Feed, delimiter: str) -> Iterator[tuple[int, list[str]]]:
    for cells in csv.reader(feed, delimiter=delimiter):
        feed.between = True
        if cells:
            yield feed.start + 1, cells


class _Feed:
    """The lines of ``lines`` from ``k`` for csv.reader, skipping empty and comment lines
    where a record begins (never inside a quoted cell); ``start``: the index of the line
    the current record began on."""

    def __init__(self, lines: list[str], k: int) -> None:
        self.lines, self.next, self.start, self.between = lines, k, k, True

    def __iter__(self) -> Iterator[str]:
        return self

    def __next__(self) -> str:
        while self.next < len(self.lines):
            n = self.next
            self.next += 1
            if self.between:
                if _skipped(self.lines[n]):
                    continue
                self.start, self.between = n, False
            return self.lines[n]
        raise StopIteration


def _first(lines: list[str], k: int) -> int:
    """The index of the first line from ``k`` that is not skipped (len: none)."""
    while k < len(lines) and _skipped(lines[k]):
        k += 1
    return k


def _skipped(line: str) -> bool:
    return not line.strip() or line.lstrip().startswith("#")
