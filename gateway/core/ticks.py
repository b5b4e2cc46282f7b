"""Time rules of polling, as plain objects: every method takes ``now`` and reads no clock.

* :class:`ProcessClock`: process time from wall time (``time_scale`` for simulation).
* :class:`TickGrid`: the absolute tick schedule of a device and the ticks missed when a
  poll overran (recorded as gap rows, never made up in a burst).
* :class:`Backoff`: capped, full-jitter exponential delays between reconnect attempts, with
  a longer cap after a refused login (so a plant's account is not locked).
* :class:`Link`: a device's up/down state and when it may be tried again; it says when the
  device goes down and when it recovers, so each outage is logged once.
* :class:`StaleTracker`: which loops have had no fresh sample for :data:`STALE_POLLS` polls.
* :class:`SetTracker`: which members of a set (failing blocks, bad points) came and went.
* :class:`Lag`: whether a device keeps its poll interval (fewer than one tick in ten missed
  over the last minute); :func:`missed_times`: when the missed ticks were due (each gap row
  keeps its own time).
* :func:`stalled`: whether a poller made no progress for longer than a tick may take.

The runtime's poller reads the clocks once per tick and passes them in; tests pass numbers.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import random
from collections.abc import Hashable, Iterable, Mapping

import numpy as np
from numpy.typing import NDArray

__all__ = ["AUTH_RETRY_CAP_S", "LAG_WINDOW_S", "STALE_POLLS", "Backoff", "Lag", "Link",
           "ProcessClock", "SetTracker", "StaleTracker", "TickGrid", "missed_times", "stalled"]

STALE_POLLS = 3
"""Polls without a fresh sample after which a loop is stale (verdict code 6)."""
AUTH_RETRY_CAP_S = 60.0
"""Least cap of the backoff after a refused login or certificate (kind ``auth``): from the
first refusal on, the next attempt waits between half of it and all of it (30-60 s)."""
LAG_WINDOW_S = 60.0
"""The window over which :class:`Lag` counts a device's missed ticks (or 10 intervals, if
longer)."""


@dataclasses.dataclass(frozen=True)
class ProcessClock:
    """Process time: Unix time at ``time_scale`` 1, else start + elapsed × time_scale."""

    time_scale: float
    start: float  # wall time (Unix seconds) the clock started

    def now(self, wall: float) -> float:
        return self.start + (wall - self.start) * self.time_scale


@dataclasses.dataclass(frozen=True)
class TickGrid:
    """Ticks every ``period`` seconds (loop time); with ``phase_ref`` on the grid
    ``phase_ref + n * period``, else from the first tick on."""

    period: float
    phase_ref: float | None = None

    def first_due(self, now: float) -> float:
        """The first tick at or after ``now``."""
        if self.phase_ref is None:
            return now
        return self.phase_ref + math.ceil((now - self.phase_ref) / self.period) * self.period

    def catch_up(self, due: float, now: float) -> tuple[int, float]:
        """``(missed, due)``: ticks whose time passed while the previous tick overran, and
        the due time of the tick to run now (the latest one that has passed)."""
        behind = now - due
        if behind < self.period:
            return 0, due
        missed = int(behind // self.period)
        return missed, due + missed * self.period


def missed_times(due: float, missed: int, period: float, rows: int) -> list[float]:
    """When the last ``rows`` of the ``missed`` ticks from ``due`` on were due (the earlier
    ones would not fit the window anyway), oldest first."""
    first = max(0, missed - rows)
    return [due + k * period for k in range(first, missed)]


class Lag:
    """Whether a device keeps its poll interval ``period``: it falls *behind* once the ticks
    it missed within the last ``window_s`` (default :data:`LAG_WINDOW_S`, or 10 intervals
    if longer) reach a tenth of the window's ticks (at least 2), and catches up when they
    fall under a twentieth. A lone hiccup is not a device that cannot keep its interval
    (its missed tick is still counted and is still a gap); a device that misses one tick in
    ten is, and stays flagged for up to a window after."""

    def __init__(self, period: float, window_s: float | None = None) -> None:
        self.period = period
        self.window_s = window_s or max(LAG_WINDOW_S, 10 * period)
        self.behind = False
        self.missed = 0  # ticks missed within the window
        self._events: collections.deque[tuple[float, int]] = collections.deque()
        self._start: float | None = None

    def ticks(self, now: float) -> float:
        """Ticks the window holds at ``now`` (at least 10: a fresh start is judged too)."""
        start = now if self._start is None else self._start
        return max(10.0, min(self.window_s, now - start) / self.period)

    def update(self, now: float, missed: int) -> bool | None:
        """A tick starts at ``now`` after ``missed`` missed ones. True when the device just
        fell behind, False when it just caught up, else None."""
        if self._start is None:
            self._start = now
        if missed:
            self._events.append((now, missed))
            self.missed += missed
        while self._events and now - self._events[0][0] > self.window_s:
            self.missed -= self._events.popleft()[1]
        ticks = self.ticks(now)
        if not self.behind and self.missed >= max(2.0, 0.10 * ticks):
            self.behind = True
            return True
        if self.behind and self.missed < 0.05 * ticks:
            self.behind = False
            return False
        return None


class Backoff:
    """Delays for successive reconnect attempts: ``uniform(0, min(cap, base·factor^n))``
    ("full jitter"), so many gateways or devices that lost a PLC at the same moment do not
    retry in lock-step. ``caps`` gives a kind of failure its own delay, from the first such
    failure on: ``uniform(cap/2, cap)`` (default: a refused login waits 30-60 s, at least
    :data:`AUTH_RETRY_CAP_S`, so that a wrong password does not lock a plant's account;
    ramping up from half a second tried 5 logins in the first 10 s). ``reset()`` after a
    success.
    """

    def __init__(self, base: float = 0.5, factor: float = 2.0, cap: float = 30.0,
                 rng: random.Random | None = None,
                 caps: Mapping[str, float] | None = None) -> None:
        if base <= 0:
            raise ValueError(f"`base` must be > 0, was {base}")
        if factor < 1:
            raise ValueError(f"`factor` must be >= 1, was {factor}")
        if cap < base:
            raise ValueError(f"`cap` must be >= base, was {cap}")
        self.base, self.factor, self.cap = base, factor, cap
        self.caps = dict(caps) if caps is not None else {"auth": max(cap, AUTH_RETRY_CAP_S)}
        self.attempt = 0
        self._rng = rng or random.Random()

    def cap_for(self, kind: str | None = None) -> float:
        """The cap of the delays after a failure of ``kind``."""
        return self.caps.get(kind, self.cap) if kind is not None else self.cap

    def ceiling(self, kind: str | None = None) -> float:
        """Upper bound of the next delay (after a failure of ``kind``)."""
        if kind is not None and kind in self.caps:
            return self.caps[kind]
        return min(self.cap_for(kind), self.base * self.factor ** min(self.attempt, 64))

    def next_delay(self, kind: str | None = None) -> float:
        if kind is not None and kind in self.caps:
            cap = self.caps[kind]
            delay = self._rng.uniform(cap / 2, cap)
        else:
            delay = self._rng.uniform(0.0, self.ceiling(kind))
        self.attempt += 1
        return delay

    def reset(self) -> None:
        self.attempt = 0


class Link:
    """A device's up/down state. ``up`` is None until the first poll decided."""

    def __init__(self, backoff: Backoff) -> None:
        self.backoff = backoff
        self.up: bool | None = None
        self.retry_at = 0.0  # no connect attempt before this (loop time)

    def may_connect(self, now: float) -> bool:
        return now >= self.retry_at

    def failed(self, kind: str, now: float) -> bool:
        """A connect or read failed: back off. True when the device just went down."""
        went_down = self.up is not False
        self.up = False
        self.retry_at = now + self.backoff.next_delay(kind)
        return went_down

    def answered(self) -> bool | None:
        """A read succeeded: reset the backoff. Returns the state before (False: the
        device just recovered; None: its first answer; True: it was up)."""
        before = self.up
        self.up = True
        self.backoff.reset()
        return before


class StaleTracker:
    """Stale flags of ``n`` loops: stale once :data:`STALE_POLLS` polls went by without a
    fresh sample (one the device delivered, good or bad), or from poll STALE_POLLS + 1 on
    when there never was one."""

    def __init__(self, n: int, polls: int = STALE_POLLS) -> None:
        self.polls = polls
        self.last_fresh = np.full(n, -1, dtype=np.int64)

    def update(self, poll: int, fresh: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Record poll number ``poll`` (1, 2, ...); returns the stale flags after it."""
        self.last_fresh[fresh] = poll
        last = self.last_fresh
        return ((last < 0) & (poll > self.polls)) | ((last >= 0) & (poll - last >= self.polls))


class SetTracker:
    """The current members of a set; :meth:`update` says which came and which went."""

    def __init__(self, members: Iterable[Hashable] = ()) -> None:
        self.members: frozenset[Hashable] = frozenset(members)

    def update(self, members: Iterable[Hashable]) -> tuple[list[Hashable], list[Hashable]]:
        new = frozenset(members)
        came = sorted(new - self.members, key=str)
        went = sorted(self.members - new, key=str)
        self.members = new
        return came, went


def stalled(now: float, last_progress: float | None, period: float, guard_s: float) -> bool:
    """True when no tick has ended for longer than a tick can legitimately take (a tick
    waits for at most one connect and one read, each bounded by ``guard_s``)."""
    if last_progress is None:
        return False
    return now - last_progress > period + 2 * guard_s + 1.0
