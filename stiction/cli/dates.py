"""A column of date-time cells read to Unix seconds, a chunk at a time (:class:`DateColumn`):
the forms of :mod:`.stamps` tried on every cell, the zones the stamps name read (an
ambiguous one only with ``--tz``), the repeated hour of a daylight-saving change in a named
zone read in row order.

Every form that has read every cell so far is kept until the column ends (as a rule one; two
while ``03/01/2024`` reads day-first and month-first), and the first that read them all is
taken, of two that did the one under which time never goes back."""

from __future__ import annotations

import dataclasses
import datetime as dt
import zoneinfo
from collections.abc import Sequence

import numpy as np

from .stamps import AMBIGUOUS, DATE_FORMATS, OFFSET, SUFFIX, ZONES, ZoneError, fixed, parse

__all__ = ["DateColumn", "Dates", "read_dates"]

_EPOCH = dt.datetime(1970, 1, 1)


@dataclasses.dataclass(frozen=True)
class Dates:
    """Date-time cells read: Unix seconds and the zone to show them in."""

    seconds: np.ndarray
    zone: dt.tzinfo
    """The zone of the first stamp (``--tz``, or the one it names; UTC for one without)."""
    note: str | None = None
    """How zones named by the stamps were read, when they named any."""
    naive: bool = False
    """The stamps name no zone and no ``--tz`` was given: read as UTC (local times?)."""


@dataclasses.dataclass
class _Form:
    """One form's reading of the column so far."""

    parts: list[np.ndarray] = dataclasses.field(default_factory=list)
    prev: float = -np.inf
    named: int | None = None  # the first row whose stamp names a zone
    unnamed: int | None = None  # ... and the first that does not
    first: dt.tzinfo | None = None  # the first stamp's zone
    examples: dict[str, dt.datetime] = dataclasses.field(default_factory=dict)


class DateColumn:
    """The date-time cells of a column, added a chunk at a time (:meth:`add`), read to
    seconds at the end (:meth:`result`). Raises :class:`~.stamps.ZoneError` (with the row)
    for a zone that needs ``--tz``, or stamps with and without a zone."""

    def __init__(self, tz: dt.tzinfo | None) -> None:
        self.tz = tz
        self.forms = {f: _Form() for f in ("iso", *DATE_FORMATS)}
        self.zones: dict[str, dt.tzinfo] = {}
        self.rows = 0

    def add(self, cells: Sequence[str]) -> None:
        bodies: list[str] = []
        tokens: list[str | None] = []
        for c in cells:
            m = SUFFIX.search(c)
            if m is None or (m["abbr"] and m["abbr"].upper() in ("AM", "PM") and not m["off"]):
                bodies.append(c)
                tokens.append(None)
            else:
                bodies.append(c[:m.start()])
                tokens.append(m.group(0).strip())
        self._zones(tokens)
        for name in list(self.forms):
            stamps = _parse_all(bodies, name)
            if stamps is None:
                del self.forms[name]
                continue
            self._seconds(self.forms[name], stamps, tokens)
        self.rows += len(cells)

    def result(self) -> Dates | None:
        """The first form that read every cell (of two, the one under which time never goes
        back), or None when none did."""
        fallback = None
        for form in self.forms.values():
            seconds = np.concatenate(form.parts) if form.parts else np.empty(0)
            shown = sorted(form.examples)
            note = None if not shown else "time zones read: " + ", ".join(
                f"{k} {_offset_text(self.zones[k], form.examples[k])}" for k in shown[:6])
            naive = self.tz is None and form.named is None
            got = Dates(seconds, self.tz or form.first or dt.UTC, note, naive)
            if np.all(np.diff(seconds) >= 0):
                return got
            fallback = fallback if fallback is not None else got
        return fallback

    def _zones(self, tokens: Sequence[str | None]) -> None:
        """Each new zone token -> its zone (``--tz`` for an ambiguous one)."""
        for i, token in enumerate(tokens):
            if token is None or token in self.zones:
                continue
            abbr = token.upper()
            m = OFFSET.fullmatch(abbr)
            if m is not None:
                self.zones[token] = fixed(m)
            elif abbr in ZONES:
                self.zones[token] = dt.timezone(dt.timedelta(hours=ZONES[abbr]), abbr)
            elif self.tz is not None:
                self.zones[token] = self.tz
            elif abbr in AMBIGUOUS:
                raise ZoneError(f"zone {token!r} names several zones ({AMBIGUOUS[abbr]}): give "
                                "--tz with the historian's zone (e.g. --tz America/Chicago or "
                                "--tz -06:00)", self.rows + i)
            else:
                raise ZoneError(f"zone {token!r} is not one this reader knows: give --tz with "
                                "the historian's zone (e.g. --tz Europe/Berlin or --tz +01:00)",
                                self.rows + i)

    def _seconds(self, form: _Form, stamps: Sequence[dt.datetime],
                 tokens: Sequence[str | None]) -> None:
        out = np.empty(len(stamps))
        tz = self.tz
        fixed_at: dict[str | None, float] = {  # zone -> seconds east of UTC, fixed offsets
            k: z.utcoffset(None).total_seconds()
            for k, z in [*self.zones.items(), (None, tz or dt.UTC)]
            if isinstance(z, dt.timezone)}
        prev = form.prev
        for i, (s, token) in enumerate(zip(stamps, tokens, strict=True)):
            named = token is not None or s.tzinfo is not None
            if named and form.named is None:
                form.named = self.rows + i
            if not named and form.unnamed is None:
                form.unnamed = self.rows + i
            if token is not None and token not in form.examples:
                form.examples[token] = s
            if s.tzinfo is not None and token is None:
                out[i] = prev = s.timestamp()
            elif token in fixed_at:  # the common case: no zone, or a fixed one; ten times faster
                out[i] = prev = (s.replace(tzinfo=None) - _EPOCH).total_seconds() \
                    - fixed_at[token]
            else:
                zone = self.zones[token] if token is not None else tz or dt.UTC
                out[i] = prev = _localise(s.replace(tzinfo=None), zone, token, prev,
                                          self.rows + i).timestamp()
        if tz is None and form.named is not None and form.unnamed is not None:
            raise ZoneError("some time stamps name a zone and some do not: give --tz with the "
                            "zone of those that do not", form.unnamed)
        if not form.parts:
            form.first = stamps[0].tzinfo if tokens[0] is None else self.zones[tokens[0]]
        form.prev = prev
        form.parts.append(out)


def read_dates(cells: Sequence[str], tz: dt.tzinfo | None = None) -> Dates | None:
    """Unix seconds of every cell (:class:`DateColumn` of one chunk)."""
    column = DateColumn(tz)
    column.add(cells)
    return column.result()


def _parse_all(bodies: Sequence[str], form: str) -> list[dt.datetime] | None:
    out = []
    for b in bodies:
        stamp = parse(b, form)
        if stamp is None:
            return None
        out.append(stamp)
    return out


def _localise(s: dt.datetime, zone: dt.tzinfo, token: str | None, prev: float, row: int
              ) -> dt.datetime:
    """A wall-clock time in ``zone``: in the repeated hour of a daylight-saving change the
    one whose abbreviation is ``token``, else the one that does not go back in time."""
    first = s.replace(tzinfo=zone)
    if not isinstance(zone, zoneinfo.ZoneInfo):
        return first
    second = s.replace(tzinfo=zone, fold=1)
    if token is not None:
        for c in (first, second):
            if c.tzname() == token.upper():
                return c
        raise ZoneError(f"zone {token!r} is not {zone.key}'s at {s:%Y-%m-%d %H:%M} "
                        f"({first.tzname()}): give --tz with the historian's zone", row)
    if first.utcoffset() != second.utcoffset() and first.timestamp() < prev:
        return second
    return first


def _offset_text(zone: dt.tzinfo, at: dt.datetime) -> str:
    off = zone.utcoffset(at.replace(tzinfo=None)) or dt.timedelta(0)
    minutes = int(off.total_seconds() // 60)
    sign = "-" if minutes < 0 else "+"
    return f"{sign}{abs(minutes) // 60:02d}:{abs(minutes) % 60:02d}"
