"""Time stamps as historians write them, read to Unix seconds.

ISO 8601 (``2024-03-01 06:00:00``, ``...T06:00:00.5Z``, ``...+01:00``) and the common
date-times of :data:`DATE_FORMATS`, each with fractional seconds, with or without a zone
after the time: an offset (``+01:00``, ``UTC+1``, ``GMT-5``) or an abbreviation of
:data:`ZONES` (``CET``, ``CEST``, ``EST``, ...). An abbreviation that names several zones
(:data:`AMBIGUOUS`: ``CST`` is US Central, China or Cuba) is read only with ``--tz``, the
historian's zone (an IANA name such as ``America/Chicago``, whose ``CST`` and ``CDT`` then
pick the hour of a daylight-saving change, or an offset such as ``-06:00``); ``--tz`` is
also the zone of stamps that name none (else UTC), a repeated hour at the end of summer
time read in the order of the rows.
"""

from __future__ import annotations

import datetime as dt
import functools
import re
import zoneinfo
from collections.abc import Sequence

import numpy as np

__all__ = ["AMBIGUOUS", "DATE_FORMATS", "EPOCH_UNITS", "EXAMPLES", "OFFSET", "SUFFIX", "ZONES",
           "ZoneError", "epoch_unit", "fixed", "is_date", "is_time_of_day", "parse", "parse_tz",
           "serial_days", "serial_text", "times_of_day"]

DATE_FORMATS = (
    "%d.%m.%Y %H:%M:%S", "%d.%m.%Y %H:%M",            # 01.03.2024 06:00:00
    "%d/%m/%Y %H:%M:%S", "%d/%m/%Y %H:%M",            # 01/03/2024 06:00:00
    "%m/%d/%Y %H:%M:%S", "%m/%d/%Y %H:%M",            # 03/01/2024 06:00:00
    "%m/%d/%Y %I:%M:%S %p", "%m/%d/%Y %I:%M %p",      # 3/1/2024 6:00:00 AM
    "%d-%b-%Y %H:%M:%S", "%d-%b-%y %H:%M:%S",          # 01-Mar-2024 06:00:00 (PI)
    "%Y/%m/%d %H:%M:%S",                               # 2024/03/01 06:00:00
)
"""Date-time forms tried after ISO 8601, each also with fractional seconds; day-first and
month-first both parse as the one under which time never goes back."""
EXAMPLES = ("seconds, or dates like 2024-03-01 06:00:00, 2024-03-01T06:00:00Z, "
            "01.03.2024 06:00:00, 3/1/2024 6:00:00 AM, 2024-03-01 06:00:00 CET")

ZONES: dict[str, float] = {
    "UTC": 0, "UT": 0, "GMT": 0, "Z": 0, "WET": 0, "WEST": 1, "CET": 1, "CEST": 2,
    "MET": 1, "MEST": 2, "MEZ": 1, "MESZ": 2, "EET": 2, "EEST": 3, "MSK": 3, "SAST": 2,
    "WAT": 1, "CAT": 2, "EAT": 3, "PKT": 5, "ICT": 7, "WIB": 7, "HKT": 8, "SGT": 8,
    "AWST": 8, "JST": 9, "KST": 9, "ACST": 9.5, "ACDT": 10.5, "AEST": 10, "AEDT": 11,
    "NZST": 12, "NZDT": 13, "NST": -3.5, "NDT": -2.5, "ADT": -3, "EST": -5, "EDT": -4,
    "MST": -7, "MDT": -6, "PST": -8, "PDT": -7, "AKST": -9, "AKDT": -8, "HST": -10,
    "BRT": -3, "ART": -3,
}
"""Zone abbreviations read as they are, hours east of UTC."""
AMBIGUOUS: dict[str, str] = {
    "CST": "US Central -06:00, China +08:00 or Cuba -05:00",
    "CDT": "US Central -05:00 or Cuba -04:00",
    "IST": "India +05:30, Ireland +01:00 or Israel +02:00",
    "BST": "British summer +01:00 or Bangladesh +06:00",
    "AST": "Atlantic -04:00 or Arabia +03:00",
    "GST": "Gulf +04:00 or South Georgia -02:00",
    "SST": "Samoa -11:00 or Singapore +08:00",
}
"""Abbreviations that name several zones: read only with ``--tz``."""

SUFFIX = re.compile(r"\s+(?:(?P<abbr>[A-Za-z]{1,5})(?P<off>[+-]\d{1,2}(?::?\d{2})?)?"
                     r"|(?P<num>[+-]\d{2}:?\d{2}))$")
_EPOCH = dt.datetime(1970, 1, 1)
OFFSET = re.compile(r"(?:UTC|GMT)?([+-])(\d{1,2})(?::?(\d{2}))?")


class ZoneError(Exception):
    """A zone the stamps name that cannot be read without ``--tz`` (``row``: its first)."""

    def __init__(self, message: str, row: int) -> None:
        super().__init__(message)
        self.row = row


def parse_tz(text: str) -> dt.tzinfo:
    """``--tz``: an IANA zone name (``Europe/Berlin``), ``UTC``, or an offset (``+01:00``,
    ``-0500``, ``UTC+1``); ValueError naming what it may be."""
    m = OFFSET.fullmatch(text.strip())
    if m:
        return fixed(m)
    if text.strip().upper() in ("UTC", "GMT", "Z"):
        return dt.UTC
    try:
        return zoneinfo.ZoneInfo(text.strip())
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ValueError(f"unknown zone {text!r}: give an IANA zone such as Europe/Berlin or "
                         "America/Chicago, or an offset such as +01:00") from None


def fixed(m: re.Match[str]) -> dt.timezone:
    sign = -1 if m[1] == "-" else 1
    return dt.timezone(sign * dt.timedelta(hours=int(m[2]), minutes=int(m[3] or 0)))


_FIELDS = {
    "d": r"(?P<d>\d{1,2})", "m": r"(?P<m>\d{1,2})", "Y": r"(?P<Y>\d{4})", "y": r"(?P<y>\d{2})",
    "H": r"(?P<H>\d{1,2})", "I": r"(?P<H>\d{1,2})", "M": r"(?P<M>\d{1,2})",
    "S": r"(?P<S>\d{1,2})(?:\.(?P<f>\d{1,6}))?", "p": r"(?P<p>[AaPp][Mm])",
    "b": r"(?P<b>[A-Za-z]{3})",
}
_MONTHS = {m: i for i, m in enumerate(
    ("jan", "feb", "mar", "apr", "may", "jun", "jul", "aug", "sep", "oct", "nov", "dec"), 1)}


@functools.cache
def _pattern(form: str) -> re.Pattern[str]:
    """A strptime form as a regular expression (strptime itself is ten times slower)."""
    parts = re.split(r"%(\w)", form)
    return re.compile("".join(_FIELDS[p] if i % 2 else re.escape(p)
                              for i, p in enumerate(parts)))


def parse(cell: str, form: str) -> dt.datetime | None:
    """The cell as ISO 8601 (``form`` "iso") or as a form of :data:`DATE_FORMATS` (read
    as :func:`datetime.datetime.strptime` does, fractional seconds allowed), or None."""
    try:
        if form == "iso":
            if cell[:4].isdigit() and len(cell) >= 10 and cell[4] == "-":
                return dt.datetime.fromisoformat(cell)
            return None
        m = _pattern(form).fullmatch(cell)
        if m is None:
            return None
        g = m.groupdict()
        year = int(g["Y"]) if g.get("Y") else 2000 + int(g["y"]) - (100 if int(g["y"]) > 68
                                                                       else 0)
        month = int(g["m"]) if g.get("m") else _MONTHS.get(g["b"].casefold(), 0)
        hour = int(g["H"])
        if g.get("p"):
            if not 1 <= hour <= 12:
                return None
            hour = hour % 12 + (12 if g["p"].upper() == "PM" else 0)
        micro = int((g.get("f") or "0").ljust(6, "0"))
        return dt.datetime(year, month, int(g["d"]), hour, int(g["M"]), int(g.get("S") or 0),
                           micro)
    except ValueError:
        return None


def is_date(cell: str) -> bool:
    """Whether one form reads the cell (its zone aside)."""
    m = SUFFIX.search(cell)
    body = cell if m is None else cell[:m.start()]
    return any(parse(body, f) is not None for f in ("iso", *DATE_FORMATS))


EPOCH_UNITS = (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9))
"""Units of Unix time other than seconds that exports write (Ignition's ``t_stamp`` and
most web historians: milliseconds; InfluxDB: nanoseconds), with their count per second."""
_YEARS = (946_684_800.0, 4_102_444_800.0)  # 2000-01-01 and 2100-01-01 in Unix seconds


def epoch_unit(values: np.ndarray) -> tuple[str, float] | None:
    """``(unit, per_second)`` when every number of a time column is a Unix time of this
    century in one of :data:`EPOCH_UNITS` (the ranges do not overlap: seconds of this
    century are 9.5e8 to 4.1e9, milliseconds 9.5e11 to 4.1e12, ...); None otherwise, the
    numbers then being seconds as they are. Judged from the magnitude alone, so one value
    (a ``--from`` time) reads as its column does."""
    x = values[np.isfinite(values)]
    if x.size == 0:
        return None
    lo, hi = float(x.min()), float(x.max())
    for unit, per_second in EPOCH_UNITS:
        if _YEARS[0] * per_second <= lo and hi <= _YEARS[1] * per_second:
            return unit, per_second
    return None


_SERIAL_EPOCH = 25_569.0  # 1970-01-01 as a spreadsheet serial date (days since 1899-12-30)


def serial_days(values: np.ndarray) -> bool:
    """Whether a time column's numbers look like spreadsheet serial dates (days since
    1899-12-30 with the time of day as a fraction, as Excel writes a date-time cell saved
    as a number): every one within 1970-2100 (25,569 to 73,051) and the rows at most an
    hour apart (a step of 1/24 or less), which as seconds would be a recording sampled
    faster than 24 times a second that starts seven hours or more into its clock."""
    x = values[np.isfinite(values)]
    if x.size < 2:
        return False
    steps = np.diff(x)
    steps = steps[steps > 0]
    return bool(x.min() >= _SERIAL_EPOCH and x.max() <= 73_051.0 and steps.size
                and float(np.median(steps)) <= 1.0 / 24.0)


def serial_text(value: float) -> str:
    """A spreadsheet serial date as the date-time it stands for (UTC), for messages."""
    when = _EPOCH + dt.timedelta(days=value - _SERIAL_EPOCH)
    return when.strftime("%Y-%m-%d %H:%M:%S")


_TIME_OF_DAY = re.compile(r"^(\d{1,2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?(?:\s*([AaPp][Mm]))?$")


def is_time_of_day(cell: str) -> bool:
    """Whether the cell is a time of day without a date (``06:00:00``, ``6:00 AM``)."""
    return _TIME_OF_DAY.match(cell.strip()) is not None


def times_of_day(cells: Sequence[str], state: tuple[float, float] = (0.0, -np.inf)
                 ) -> tuple[np.ndarray, tuple[float, float]] | None:
    """Seconds from midnight of the first row's day of cells that are all times of day, a
    day added each time the clock goes back more than 12 hours (it passed midnight); None
    when a cell is not a time of day. ``state`` (the day added so far and the last time)
    carries the count from one chunk of a column to the next; the new state is returned."""
    out = np.empty(len(cells))
    day, last = state
    for i, cell in enumerate(cells):
        m = _TIME_OF_DAY.match(cell.strip())
        if m is None:
            return None
        hours, minutes, secs = int(m[1]), int(m[2]), float(m[3] or 0.0)
        if m[4]:
            hours = hours % 12 + (12 if m[4].upper() == "PM" else 0)
        t = day + 3600.0 * hours + 60.0 * minutes + secs
        if t < last - 43_200.0:
            day += 86_400.0
            t += 86_400.0
        out[i] = last = t
    return out, (day, last)
