"""The engineer's findings (``findings: findings.csv`` in the config): what the crew found at
a valve, kept by the plant under version control beside the config (docs/configuration.md,
"Findings").

A CSV file like a tag list: the first line that is not empty or a ``#`` comment is the
header, naming the columns of :data:`COLUMNS` in any order and any case (``,``, ``;`` or
tab separated, or as a first line ``sep=;`` says; empty columns after the last named one
are ignored), then one finding per row; the text as a spreadsheet saves it (UTF-8, UTF-16,
Windows-1252), a cell in double quotes over several lines: :mod:`.csvfile`::

    loop,date,finding,fd,fs,by,note
    FIC101,2024-03-05,stiction,2.5,3.1,J. Doe,packing tightened
    TIC301,2024-03-07,ok,,,J. Doe,cycle from the steam header

Every row is checked; a bad row is named (file, line, what is wrong) and skipped, never
fatal: the good rows are used. :func:`read_findings` returns them with the problems; a file
that cannot be read at all (missing, unreadable, no header) says so in ``problems`` with
``readable`` False, and the gateway keeps the findings it had (:mod:`gateway.core.findings`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import re
from collections.abc import Collection
from pathlib import Path
from typing import Any

from .csvfile import DecodeError, decode, records
from .reading import read_bytes

__all__ = ["COLUMNS", "FINDINGS", "MAX_FINDINGS_BYTES", "REQUIRED", "Finding", "FindingsFile",
           "findings_path", "parse_findings", "read_findings", "verdicts_path"]

FINDINGS = ("stiction", "deadband", "ok", "other")
"""What the crew found: ``stiction`` (the valve sticks), ``deadband`` (lost motion, no
stick-slip: worn linkage, loose positioner), ``ok`` (the valve is fine: the cause is
elsewhere), ``other`` (a valve problem of another kind: sized wrong, cavitating, ...)."""
COLUMNS: dict[str, str] = {
    "loop": "the loop's name, as in the config",
    "date": "when the crew found it: YYYY-MM-DD (a date-time's date is taken), from 1970",
    "finding": "one of " + ", ".join(FINDINGS),
    "fd": "dynamic friction fd, % of span (optional)",
    "fs": "static friction fs, % of span (optional)",
    "deadband": "a step test's dead band, % of span (optional): fs + fd, what `stiction "
                "valve-test` prints as `dead band` (never write it in fd)",
    "resolution": "a step test's resolution, % of span (optional): fs - fd; with the dead "
                  "band, fd and fs are worked out",
    "by": "who found it (optional)",
    "note": "what was found or done (optional)",
}
REQUIRED = ("loop", "date", "finding")
MAX_FINDINGS_BYTES = 8 * 1024 * 1024
"""A findings file larger than this is not read (the gateway keeps what it had)."""
MAX_TEXT = 500  # characters of ``by`` and ``note`` kept
FIRST_DATE = dt.date(1970, 1, 2)
"""The earliest date a finding may have: before it, no gateway had a verdict (Unix time and
the verdict history begin in 1970; a day later, so that its local midnight is a Unix time
in every time zone). ``0001-01-01`` is many maintenance systems' "no date"."""
_DAY_FIRST = re.compile(r"(\d{1,2})\.(\d{1,2})\.(\d{4})")


@dataclasses.dataclass(frozen=True)
class Finding:
    """One row: ``fd`` and ``fs`` in % of span (None: not measured; worked out from a step
    test's ``deadband`` and ``resolution`` where those were written); ``line`` in the
    file."""

    loop: str
    date: dt.date
    finding: str
    fd: float | None = None
    fs: float | None = None
    by: str = ""
    note: str = ""
    line: int = 0
    deadband: float | None = None  # a step test's dead band (fs + fd), as written
    resolution: float | None = None  # and its resolution (fs - fd)


@dataclasses.dataclass(frozen=True)
class FindingsFile:
    """A read findings file: its good rows, one line per problem, and whether the file
    could be read at all (False: keep the findings you had)."""

    source: str
    findings: tuple[Finding, ...] = ()
    problems: tuple[str, ...] = ()
    readable: bool = True


def findings_path(config_source: str, value: str) -> Path:
    """The file ``findings: value`` names, relative to the config file's folder."""
    path = Path(value).expanduser()
    if path.is_absolute():
        return path
    config = Path(config_source)
    return (config.parent if config.is_file() else Path()) / path


def verdicts_path(state_file: str) -> Path:
    """The verdict history's file, beside the state file: ``gateway.state`` ->
    ``gateway.verdicts`` (``NAME`` -> ``NAME.verdicts`` without a suffix)."""
    p = Path(state_file)
    out = p.with_suffix(".verdicts") if p.suffix else p.with_name(p.name + ".verdicts")
    return out if out != p else p.with_name(p.name + ".verdicts")


def read_findings(path: str | Path, loops: Collection[str], *, today: dt.date,
                  shown_as: str | None = None) -> FindingsFile:
    """Read and check a findings file against the config's ``loops``; never raises."""
    source = shown_as or str(path)
    try:
        data = read_bytes(path, MAX_FINDINGS_BYTES)  # a regular file, within a time limit
    except OSError as exc:
        return FindingsFile(source, (), (f"{source}: cannot read: {exc.strerror or exc}",),
                            readable=False)
    if len(data) > MAX_FINDINGS_BYTES:
        return FindingsFile(source, (), (f"{source}: larger than {MAX_FINDINGS_BYTES:,} bytes,"
                                         " the most a findings file may have",), readable=False)
    try:
        text = decode(data)
    except DecodeError as exc:
        return FindingsFile(source, (), (f"{source}: line {exc.line}: neither UTF-8 nor "
                                         "Windows-1252 (save the file as CSV UTF-8)",),
                            readable=False)
    return parse_findings(text, source, loops, today=today)


def parse_findings(text: str, source: str, loops: Collection[str], *, today: dt.date
                   ) -> FindingsFile:
    delimiter, rows = records(text)
    first = next(rows, None)
    if first is None:
        return FindingsFile(source, (), (f"{source}: no header row (columns: "
                                         f"{', '.join(COLUMNS)})",), readable=False)
    head_line, cells = first
    header = [c.strip().lower() for c in cells]
    while header and not header[-1]:  # a spreadsheet's empty columns after the last
        header.pop()
    named = len(header)
    where = f"{source}: line {head_line}"
    problems = [f"{where}: unknown column {c!r} (known: {', '.join(COLUMNS)})"
                for c in dict.fromkeys(header) if c not in COLUMNS]
    problems += [f"{where}: column {c!r} appears twice" for c in COLUMNS if header.count(c) > 1]
    missing = [c for c in REQUIRED if c not in header]
    if missing or problems:
        problems += [f"{where}: missing column(s) {', '.join(map(repr, missing))}"] if missing \
            else []
        return FindingsFile(source, (), tuple(problems), readable=False)
    out: list[Finding] = []
    seen: dict[tuple[Any, ...], int] = {}
    for n, record in rows:
        cells = record[:named] if not "".join(record[named:]).strip() else record
        if len(cells) != named:  # (empty cells after the last named column are no cells)
            problems.append(f"{source}: line {n} has {len(cells)} cells, the header has "
                            f"{named}: make the row one cell per column (an empty "
                            "cell for an empty value; a cell holding the delimiter or a "
                            "line break in double quotes)")
            continue
        row = {c: cell.strip() for c, cell in zip(header, cells, strict=True)}
        finding, why = _row(row, n, loops, today, delimiter != ",")
        if finding is None:
            name = row.get("loop")
            problems.append(f"{source}: line {n}" + (f": loop {name}" if name else "")
                            + f": {why}")
            continue
        key = (finding.loop, finding.date, finding.finding, finding.fd, finding.fs,
               finding.by, finding.note, finding.deadband)
        if key in seen:
            problems.append(f"{source}: line {n}: loop {finding.loop}: repeats line "
                            f"{seen[key]}")
            continue
        seen[key] = n
        out.append(finding)
    return FindingsFile(source, tuple(out), tuple(problems))


def _row(row: dict[str, str], n: int, loops: Collection[str], today: dt.date,
         comma: bool) -> tuple[Finding | None, str]:
    loop = row["loop"]
    if not loop:
        return None, "column 'loop': required, but empty"
    if loop not in loops:
        return None, f"column 'loop': no loop {loop!r} in the config"
    date = _date(row["date"])
    if date is None:
        return None, (f"column 'date': {row['date']!r} is not a date (write YYYY-MM-DD, e.g. "
                      f"{today.isoformat()})")
    if date > today + dt.timedelta(days=1):
        return None, f"column 'date': {date.isoformat()} is in the future"
    if date < FIRST_DATE:
        return None, (f"column 'date': {row['date']!r} is before {FIRST_DATE.year} (the "
                      "'no date' of a maintenance system's export?): write the day the crew "
                      "found it")
    kind = row["finding"].lower()
    if kind not in FINDINGS:
        return None, (f"column 'finding': must be one of {', '.join(FINDINGS)}, "
                      f"was {row['finding']!r}")
    sizes: dict[str, float | None] = {}
    for col in ("fd", "fs", "deadband", "resolution"):
        cell = row.get(col, "")
        sizes[col] = None
        if cell:
            value = _number(cell, comma)
            if value is None or not 0.0 <= value <= 100.0:
                return None, (f"column {col!r}: must be a number of % of span (0 to 100), "
                              f"was {cell!r}")
            sizes[col] = value
    fd, fs, why = _frictions(sizes["fd"], sizes["fs"], sizes["deadband"], sizes["resolution"])
    if why:
        return None, why
    return Finding(loop, date, kind, fd, fs, _text(row.get("by", "")),
                   _text(row.get("note", "")), n, sizes["deadband"], sizes["resolution"]), ""


STEP_TEST = ("a step test's dead band is fs + fd and its resolution fs - fd: write them in "
             "'deadband' and 'resolution' and leave fd and fs empty, they are worked out")
SLACK = 0.05  # % of span: rounding of figures written with one decimal


def _frictions(fd: float | None, fs: float | None, deadband: float | None,
               resolution: float | None) -> tuple[float | None, float | None, str]:
    """fd and fs of a row, worked out from a step test's dead band (fs + fd) and resolution
    (fs - fd) where those are written, and checked against them where both are (issue 38
    item 12: the docs' example put a dead band in fd); a problem, or ""."""
    if deadband is not None and resolution is not None and resolution > deadband + SLACK:
        return None, None, (f"column 'resolution': {resolution:g} exceeds the dead band "
                            f"{deadband:g} ({STEP_TEST})")
    if deadband is not None:
        if fd is None and fs is None and resolution is not None:
            fs, fd = (deadband + resolution) / 2, (deadband - resolution) / 2
        elif fd is not None and fs is None:
            fs = deadband - fd
        elif fs is not None and fd is None:
            fd = deadband - fs
        elif fd is not None and fs is not None and abs(fd + fs - deadband) > SLACK:
            return None, None, (f"column 'fd': fd {fd:g} + fs {fs:g} = {fd + fs:g} is not the "
                                f"dead band {deadband:g} ({STEP_TEST})")
        if fd is not None and fs is not None and resolution is not None \
                and abs(fs - fd - resolution) > SLACK:
            return None, None, (f"column 'resolution': fs {fs:g} - fd {fd:g} = {fs - fd:g} is "
                                f"not the resolution {resolution:g} ({STEP_TEST})")
    elif resolution is not None:
        return None, None, f"column 'resolution': written without a dead band ({STEP_TEST})"
    hint = "" if deadband is None else f" ({STEP_TEST})"
    if fd is not None and fs is not None and fd > fs + (0.0 if deadband is None else SLACK):
        return None, None, f"column 'fd': {fd:g} exceeds fs {fs:g} (fd is never above fs){hint}"
    if (fd is not None and fd < 0) or (fs is not None and fs < 0):
        return None, None, f"column 'fd': below 0 with the dead band {deadband}{hint}"
    return fd, fs, ""


def _date(cell: str) -> dt.date | None:
    m = _DAY_FIRST.fullmatch(cell)
    try:
        if m:
            return dt.date(int(m[3]), int(m[2]), int(m[1]))
        if len(cell) >= 10 and cell[4] == "-":
            return dt.datetime.fromisoformat(cell).date() if len(cell) > 10 else \
                dt.date.fromisoformat(cell)
    except ValueError:
        return None
    return None


def _number(cell: str, comma: bool) -> float | None:
    try:
        value = float(cell.replace(",", ".") if comma else cell)
    except ValueError:
        return None
    return value if math.isfinite(value) else None  # NaN, inf: no number here


def _text(cell: str) -> str:
    clean = "".join(ch if ch.isprintable() else " " for ch in cell)
    return clean[:MAX_TEXT]
