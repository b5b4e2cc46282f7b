"""An export read into a :class:`Table`: the delimiter sniffed from the header and the
first rows (``,``, ``;`` or tab; an Excel ``sep=;`` first line is obeyed), a UTF-8 or UTF-16
byte-order mark, Windows-1252 when the file is not UTF-8, lines of a preamble before the
header, rows of units or descriptions under it and a header repeated where two exports were
appended skipped and said. Its columns are read by :mod:`.historian`."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
from collections.abc import Sequence
from pathlib import Path

from . import decimals, stamps
from ._common import UsageError

__all__ = ["DELIMITERS", "HEAD_ROWS", "Table", "add_reading_options", "read_table", "read_text"]

DELIMITERS = (",", ";", "\t")
HEAD_ROWS = 3
"""Rows under a header (the first, or a repeated one) skipped when they hold no number and
no time: units, descriptions."""


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
    tz: dt.tzinfo | None = None
    """The zone given (``--tz``) of stamps that name none or an ambiguous one."""
    notes: tuple[str, ...] = ()
    appended: tuple[int, ...] = ()
    """Lines where the header repeats (two exports appended)."""


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


def read_table(path: Path, *, decimal: str | None = None, tz: dt.tzinfo | None = None
               ) -> Table:
    """The file's header and rows (empty lines skipped; lines before the header that hold
    no delimiter, rows of units or descriptions under the header, and a repeated header
    with its own such rows, skipped and noted);
    ``decimal`` the decimal mark (default: decided per column, :func:`numbers`), ``tz``
    the zone of stamps that name none or an ambiguous one (:func:`times`)."""
    text, notes = read_text(path)
    lines = text.splitlines()
    first = 0
    sep = None
    if lines and lines[0].lower().startswith("sep=") and len(lines[0]) in (5, 6):
        sep, first = lines[0][4:] or "\t", 1  # Excel's hint line
    if sep is None:  # lines before the header that hold no delimiter: an export's preamble
        lead = next((i for i, line in enumerate(lines)
                     if any(d in line for d in DELIMITERS)), len(lines))
        said = [line.strip() for line in lines[:lead] if line.strip()]
        if said and lead < len(lines):
            first = lead
            shown = ", ".join(repr(x) for x in said[:3]) + (", ..." if len(said) > 3 else "")
            where = "line 1" if lead == 1 else f"lines 1-{lead}"
            notes.append(f"{where} before the header hold no column (an export's "
                         f"preamble?): skipped ({shown})")
    body = lines[first:]
    if not any(line.strip() for line in body):
        raise UsageError(f"{path}: empty file (need a header row naming the columns)")
    delimiter = sep or _sniff(body)
    reader = csv.reader(body, delimiter=delimiter)
    header: list[str] | None = None
    folded: list[str] = []
    rows: list[list[str]] = []
    at: list[int] = []
    appended: list[int] = []
    under = 0  # rows of units or descriptions skipped under the last header
    order: list[int] | None = None  # a repeated header's columns in the first one's order
    for row in reader:
        if not any(c.strip() for c in row):
            continue
        line = reader.line_num + first
        if header is None:
            header = [c.strip() for c in row]
            folded = [h.casefold() for h in header]
            continue
        cells = [c.strip().casefold() for c in row] if row[0].strip().casefold() in folded \
            else []  # a data row's first cell is no column name: the common case, quickly
        if cells and sorted(cells) == sorted(folded):
            appended.append(line)
            order = None if cells == folded else [cells.index(h) for h in folded]
            notes.append(f"the header repeats at line {line} (two exports appended?): "
                         + ("skipped" if order is None else "the rows after it put back in "
                            "the first header's column order"))
            under = 0
            continue
        if under < HEAD_ROWS and _head_row(row):
            notes.append(f"line {line} under the header holds no number and no time (units or "
                         f"a description?): skipped ({_shown(header, row)})")
            under += 1
            continue
        under = HEAD_ROWS
        rows.append(row if order is None else [row[j] if j < len(row) else "" for j in order])
        at.append(line)
    assert header is not None
    return Table(path, header, rows, at, delimiter, decimal, tz, tuple(notes), tuple(appended))


def _head_row(row: Sequence[str]) -> bool:
    """A row of units or descriptions: some text, and no cell a number or a time."""
    cells = [c.strip() for c in row if c.strip()]
    return bool(cells) and not any(decimals.is_number(c) or stamps.is_date(c) for c in cells)


def _shown(header: Sequence[str], row: Sequence[str]) -> str:
    pairs = [f"{h} {c.strip()!r}" for h, c in zip(header, row, strict=False) if c.strip()]
    return ", ".join(pairs[:6]) + (", ..." if len(pairs) > 6 else "")


def read_text(path: Path, *, named: str = "") -> tuple[str, list[str]]:
    """The file's text (UTF-16 with its byte-order mark, UTF-8 with or without one, else
    Windows-1252, said so) and the notes; ``named`` follows the path in a missing file's
    message (e.g. " (--manifest)")."""
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
