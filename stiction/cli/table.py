"""An export read into a :class:`Table`: the delimiter sniffed from the header and the
first rows (``,``, ``;`` or tab; an Excel ``sep=;`` first line is obeyed), a UTF-8 or UTF-16
byte-order mark, Windows-1252 when the file is not UTF-8, lines of a preamble before the
header, rows of units or descriptions under it and a header repeated where two exports were
appended skipped and said. Its columns are read by :mod:`.historian`.

The file is read as a stream, a chunk of rows at a time (:data:`~.cells.CHUNK_CELLS` cells
at most): only the columns asked for are kept, each compactly (:class:`~.cells.Cells`, about
one byte per character of the file), and the evidence of every column's decimal mark is
gathered on the way (:func:`~.decimals.tally_text`); the file's text is never held whole."""

from __future__ import annotations

import argparse
import array
import codecs
import csv
import dataclasses
import datetime as dt
import itertools
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from . import decimals, stamps
from ._common import UsageError
from .cells import CHUNK_CELLS, Cells

__all__ = ["DELIMITERS", "HEAD_ROWS", "Table", "add_reading_options", "read_table", "read_text",
           "tally"]

DELIMITERS = (",", ";", "\t")
HEAD_ROWS = 3
"""Rows under a header (the first, or a repeated one) skipped when they hold no number and
no time: units, descriptions."""
Select = Callable[[list[str]], Iterable[int]]
"""The columns to keep, from the header (all when not given)."""


@dataclasses.dataclass(frozen=True)
class Table:
    """A read export: the header, the columns kept (:class:`~.cells.Cells` by column index)
    with the data rows' line numbers, how it was read."""

    path: Path
    header: list[str]
    columns: Mapping[int, Cells]
    lines: np.ndarray
    delimiter: str
    decimal: str | None = None
    """The decimal mark given (``--decimal``), else None: decided per column."""
    tz: dt.tzinfo | None = None
    """The zone given (``--tz``) of stamps that name none or an ambiguous one."""
    notes: tuple[str, ...] = ()
    appended: tuple[int, ...] = ()
    """Lines where the header repeats (two exports appended)."""
    evidence: Mapping[int, dict[str, int]] = dataclasses.field(default_factory=dict)
    """Every column's evidence of its decimal mark (:func:`~.decimals.tally`), kept or not."""
    memo: dict[str, object] = dataclasses.field(default_factory=dict, compare=False,
                                                repr=False)
    """What was worked out once for the whole table (the marks OP columns settle)."""

    @property
    def size(self) -> int:
        """The number of data rows."""
        return int(self.lines.size)

    def cells(self, col: int) -> Cells:
        try:
            return self.columns[col]
        except KeyError:
            raise KeyError(f"column {self.header[col]!r} was not read") from None

    def cell(self, row: int, col: int) -> str:
        """A cell as written, stripped."""
        return self.cells(col)[row].strip()

    def reversed(self) -> Table:
        """The rows in the opposite order."""
        last = self.size - 1
        return dataclasses.replace(
            self, columns={j: c.reversed() for j, c in self.columns.items()},
            lines=self.lines[::-1].copy(),
            evidence={j: {k: last - i for k, i in e.items()} for j, e in self.evidence.items()},
            memo=dict(self.memo))


def tally(columns: Mapping[int, Cells]) -> dict[int, dict[str, int]]:
    """Each column's evidence of its decimal mark (:func:`~.decimals.tally_text`)."""
    evidence: dict[int, dict[str, int]] = {}
    for j, c in columns.items():
        evidence[j] = {}
        for start, text in c.texts():
            if decimals.tally_text(text, start, evidence[j]):
                break
    return evidence


def add_reading_options(p: argparse.ArgumentParser) -> None:
    """The options of how an export is read, for every command that reads one."""
    p.add_argument("--decimal", choices=(decimals.POINT, decimals.COMMA), default=None,
                   help="the decimal mark, when the file cannot tell (every number like "
                   "1,118 or 1.118); default: decided per column from its numbers")
    p.add_argument("--tz", type=_tz, default=None, metavar="ZONE",
                   help="the historian's time zone (Europe/Berlin, America/Chicago, +01:00): "
                   "for stamps that name no zone (default UTC) or one that names several "
                   "(CST, IST, BST, ...)")


def _tz(text: str) -> dt.tzinfo:
    try:
        return stamps.parse_tz(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def read_table(path: Path, *, decimal: str | None = None, tz: dt.tzinfo | None = None,
               select: Select | None = None) -> Table:
    """The file's header and, of its rows, the columns ``select`` names from the header
    (default: every column); empty lines skipped; lines before the header that hold no
    delimiter, rows of units or descriptions under the header, and a repeated header with
    its own such rows, skipped and noted; ``decimal`` the decimal mark (default: decided
    per column, :mod:`.historian`), ``tz`` the zone of stamps that name none or an
    ambiguous one."""
    fh, notes = _open(path)
    with fh:
        first, sep, lines = _head(fh, notes)
        if not any(line.strip() for line in lines):
            raise UsageError(f"{path}: empty file (need a header row naming the columns)")
        delimiter = sep or _sniff(lines)
        reader = csv.reader(itertools.chain(lines, fh), delimiter=delimiter)
        header = _header(reader)
        if header is None:
            raise UsageError(f"{path}: empty file (need a header row naming the columns)")
        keep = sorted(set(range(len(header)) if select is None else select(header)))
        rows = _Rows(header, keep, first, reader, notes)
        rows.read()
    return Table(path, header, rows.kept, np.array(rows.at, dtype=np.int64), delimiter, decimal,
                 tz, tuple(notes), tuple(rows.appended), rows.evidence)


def _open(path: Path) -> tuple[TextIO, list[str]]:
    """The file open as text (UTF-16 with its byte-order mark, UTF-8 with or without one,
    else Windows-1252, said so) and the notes."""
    try:
        with path.open("rb") as raw:
            head = raw.read(4)
            encoding = "utf-16" if head[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8-sig"
            if encoding != "utf-16" and not _utf8(raw, head):
                encoding = "cp1252"
        fh = path.open(encoding=encoding, errors="replace", newline="")
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from exc
    return fh, ([f"{path.name} is not UTF-8: read as Windows-1252"]
                if encoding == "cp1252" else [])


def _utf8(raw: object, head: bytes) -> bool:
    """Whether the rest of the stream ``raw`` (after ``head``) is UTF-8, read in blocks."""
    decoder = codecs.getincrementaldecoder("utf-8")()
    try:
        decoder.decode(head)
        while block := raw.read(1 << 20):  # type: ignore[attr-defined]
            decoder.decode(block)
        decoder.decode(b"", final=True)
    except UnicodeDecodeError:
        return False
    return True


def _head(fh: TextIO, notes: list[str]) -> tuple[int, str | None, list[str]]:
    """Up to the header: the index of the first line of the table, Excel's ``sep=`` if
    given, and the lines read ahead from there (the header and the first rows, for the
    delimiter); a preamble of lines without a delimiter before the header skipped, noted."""
    lines: list[str] = []
    for line in fh:
        lines.append(line)
        if any(d in line for d in DELIMITERS):
            break
    first, sep = 0, None
    if lines and lines[0].lower().startswith("sep=") and len(lines[0].rstrip("\r\n")) in (5, 6):
        sep, first = lines[0].rstrip("\r\n")[4:] or "\t", 1
    elif lines and any(d in lines[-1] for d in DELIMITERS):
        said = [line.strip() for line in lines[:-1] if line.strip()]
        first = len(lines) - 1
        if said:
            shown = ", ".join(repr(x) for x in said[:3]) + (", ..." if len(said) > 3 else "")
            where = "line 1" if first == 1 else f"lines 1-{first}"
            notes.append(f"{where} before the header hold no column (an export's "
                         f"preamble?): skipped ({shown})")
    body = lines[first:]
    body += itertools.islice(fh, 50)
    return first, sep, body


def _header(reader: Iterator[list[str]]) -> list[str] | None:
    for row in reader:
        if any(c.strip() for c in row):
            return [c.strip() for c in row]
    return None


class _Rows:
    """The data rows streamed into the kept columns, chunk by chunk, with their line
    numbers, the repeated headers and rows of units skipped, and every column's evidence of
    its decimal mark."""

    def __init__(self, header: list[str], keep: list[int], first: int, reader: Any,
                 notes: list[str]) -> None:
        self.header, self.keep, self.first, self.reader, self.notes = (
            header, keep, first, reader, notes)
        self.folded = [h.casefold() for h in header]
        self.kept = {j: Cells() for j in keep}
        self.evidence: dict[int, dict[str, int]] = {j: {} for j in range(len(header))}
        self.open = set(range(len(header)))  # columns whose decimal mark is not yet told
        self.at = array.array("q")  # the rows' line numbers
        self.appended: list[int] = []

    def read(self) -> None:
        reader, width, folded = self.reader, len(self.header), self.folded
        under = 0  # rows of units or descriptions skipped under the last header
        order: list[int] | None = None  # a repeated header's columns in the first one's order
        chunk: list[list[str]] = []
        rows = max(64, CHUNK_CELLS // max(width, 1))  # a chunk's rows: its cells bounded
        for cells_read in reader:
            row: list[str] = cells_read
            lead = row[0].strip() if row else ""
            if not lead and not any(c.strip() for c in row):
                continue
            line = reader.line_num + self.first
            cells = [c.strip().casefold() for c in row] if lead.casefold() in folded else []
            if cells and sorted(cells) == sorted(folded):
                self.appended.append(line)
                order = None if cells == folded else [cells.index(h) for h in folded]
                self.notes.append(f"the header repeats at line {line} (two exports appended?): "
                                  + ("skipped" if order is None else "the rows after it put "
                                     "back in the first header's column order"))
                under = 0
                continue
            if under < HEAD_ROWS and _head_row(row):
                self.notes.append(f"line {line} under the header holds no number and no "
                                  f"time (units or a description?): skipped "
                                  f"({_shown(self.header, row)})")
                under += 1
                continue
            under = HEAD_ROWS
            if order is not None:
                row = [row[j] if j < len(row) else "" for j in order]
            elif len(row) < width:
                row = row + [""] * (width - len(row))
            chunk.append(row)
            self.at.append(line)
            if len(chunk) == rows:
                self._flush(chunk)
                chunk = []
        self._flush(chunk)

    def _flush(self, chunk: list[list[str]]) -> None:
        if not chunk:
            return
        start = len(self.at) - len(chunk)
        cols = list(zip(*chunk, strict=False))
        for j in range(len(self.header)):
            text = None
            if j in self.open:
                text = "\n".join(cols[j])
                if decimals.tally_text(text, start, self.evidence[j]):
                    self.open.discard(j)
            if j in self.kept:
                self.kept[j].add(cols[j], text)


def _head_row(row: Sequence[str]) -> bool:
    """A row of units or descriptions: some text, and no cell a number or a time."""
    cells = [c.strip() for c in row if c.strip()]
    return bool(cells) and not any(decimals.is_number(c) or stamps.is_date(c) for c in cells)


def _shown(header: Sequence[str], row: Sequence[str]) -> str:
    pairs = [f"{h} {c.strip()!r}" for h, c in zip(header, row, strict=False) if c.strip()]
    return ", ".join(pairs[:6]) + (", ..." if len(pairs) > 6 else "")


def read_text(path: Path, *, named: str = "") -> tuple[str, list[str]]:
    """A small file's text (a manifest: UTF-16 with its byte-order mark, UTF-8 with or
    without one, else Windows-1252, said so) and the notes; ``named`` follows the path in
    a missing file's message (e.g. " (--manifest)")."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file{named}") from None
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
