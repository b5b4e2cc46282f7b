"""The engineer's findings beside the gateway's calls: no IO (the file is read by
:mod:`gateway.config.findings`, the history kept on disk by :mod:`gateway.outputs.verdicts`).

:class:`VerdictHistory` remembers, per loop, which verdict was in force on each day: the
verdict a loop *had on a date* is the one in force when that day began (before a crew's
work that day could change it), or, if the gateway had no verdict for the loop then, its
first verdict of that day. It keeps only the days on which that changed, so a loop whose
verdict flickers every analysis still costs at most one entry a day, for
:data:`RETENTION_DAYS`. ``warming_up`` is no call and is not recorded.

:class:`FindingsBook` holds the findings read last and the history, and keeps a
:class:`FindingsView` (per loop its latest finding; per site how many findings met each
verdict) up to date for the outputs, which read it from other threads; a change of one
loop's history costs that loop's findings, not the file.
"""

from __future__ import annotations

import bisect
import dataclasses
import datetime as dt
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from ..config.findings import FINDINGS, Finding, FindingsFile

__all__ = ["NOT_CALLS", "RETENTION_DAYS", "UNKNOWN", "FindingsBook", "FindingsView",
           "VerdictHistory", "day_start", "local_day"]

UNKNOWN = "unknown"
"""The verdict of a finding dated before the gateway's history of its loop."""
NOT_CALLS = frozenset({"warming_up"})
RETENTION_DAYS = 5 * 366
MAX_ENTRIES = RETENTION_DAYS + 1  # per loop: one a day at most


def local_day(t: float) -> int:
    """The local calendar day (proleptic ordinal) of Unix time ``t``."""
    return dt.datetime.fromtimestamp(t).date().toordinal()


def day_start(date: dt.date) -> float | None:
    """Unix time of the local midnight that begins ``date``; None where the platform has
    none (a date near year 1 or 9999: the findings file refuses those, and a scrape must
    never fail on one)."""
    try:
        return dt.datetime.combine(date, dt.time()).timestamp()
    except (ValueError, OverflowError, OSError):
        return None


@dataclasses.dataclass
class LoopHistory:
    """``days``/``verdicts``: from each day on (ordinal), the verdict in force when it began
    (or the day's first, for the first day); ``t``/``verdict``: the latest one seen."""

    days: list[int] = dataclasses.field(default_factory=list)
    verdicts: list[str] = dataclasses.field(default_factory=list)
    t: float = float("-inf")
    verdict: str = ""


class VerdictHistory:
    """Per loop, the verdict in force on each day (see the module docstring)."""

    def __init__(self, day_of: Callable[[float], int] = local_day) -> None:
        self.day_of = day_of
        self.loops: dict[str, LoopHistory] = {}
        self.version = 0  # bumped whenever an answer of verdict_on may have changed
        self.dirty = False  # changed since the last save
        # loops whose answers of verdict_on may have changed since the book last looked
        # (:meth:`FindingsBook.refresh` takes them): a round costs what changed
        self.changed: set[str] = set()

    def record(self, loop: str, t: float, verdict: str) -> None:
        """The loop's verdict at Unix time ``t`` (older than the latest: ignored)."""
        if verdict in NOT_CALLS:
            return
        h = self.loops.setdefault(loop, LoopHistory())
        if t <= h.t:
            return
        day = self.day_of(t)
        if not h.days:
            h.days.append(day)
            h.verdicts.append(verdict)
            self._changed(loop)
        else:
            last_day = self.day_of(h.t)
            if day > last_day and h.verdict != h.verdicts[-1]:
                h.days.append(last_day + 1)  # in force when the next day began
                h.verdicts.append(h.verdict)
                self._changed(loop)
                if len(h.days) > MAX_ENTRIES:
                    del h.days[0], h.verdicts[0]
            if verdict != h.verdict or day > last_day:  # the answer for days after the
                self.changed.add(loop)  # latest one is the latest verdict
        h.t, h.verdict = t, verdict
        self.dirty = True

    def _changed(self, loop: str) -> None:
        self.version += 1
        self.changed.add(loop)

    def verdict_on(self, loop: str, date: dt.date) -> str:
        """The verdict ``loop`` had on ``date``; :data:`UNKNOWN` before its history."""
        h = self.loops.get(loop)
        day = date.toordinal()
        if h is None or not h.days or day < h.days[0]:
            return UNKNOWN
        if day > self.day_of(h.t):
            return h.verdict  # in force since before that day began
        return h.verdicts[bisect.bisect_right(h.days, day) - 1]

    def prune(self, today: dt.date) -> None:
        """Forget the days older than :data:`RETENTION_DAYS` (a loop keeps its latest)."""
        cut = today.toordinal() - RETENTION_DAYS
        for loop, h in self.loops.items():
            k = bisect.bisect_left(h.days, cut)
            if k and k < len(h.days):
                del h.days[:k], h.verdicts[:k]
                self._changed(loop)

    def to_data(self) -> dict[str, Any]:
        """Plain values for the history file (read back with :meth:`load`)."""
        return {loop: {"days": [dt.date.fromordinal(d).isoformat() for d in h.days],
                       "verdicts": list(h.verdicts), "t": h.t, "verdict": h.verdict}
                for loop, h in self.loops.items() if h.days}

    def load(self, data: Mapping[str, Any]) -> None:
        """Take over what :meth:`to_data` wrote (checked by the reader before), merged
        under what was recorded since start: a loop's newer history wins."""
        for loop, entry in data.items():
            if loop in self.loops and self.loops[loop].t >= entry["t"]:
                continue
            self.loops[loop] = LoopHistory(
                [dt.date.fromisoformat(d).toordinal() for d in entry["days"]],
                list(entry["verdicts"]), float(entry["t"]), entry["verdict"])
            self.changed.add(loop)
        self.version += 1


@dataclasses.dataclass(frozen=True)
class FindingsView:
    """What the outputs show: per loop its latest finding (by date, then by line) and per
    (verdict on the finding's day, finding) how many findings."""

    latest: Mapping[str, Finding] = dataclasses.field(default_factory=dict)
    counts: Mapping[tuple[str, str], int] = dataclasses.field(default_factory=dict)
    problems: int = 0


def latest_of(findings: Iterable[Finding]) -> dict[str, Finding]:
    """Per loop its latest finding: the latest date, then the latest line."""
    latest: dict[str, Finding] = {}
    for f in findings:
        if f.loop not in latest or (f.date, f.line) >= (latest[f.loop].date,
                                                        latest[f.loop].line):
            latest[f.loop] = f
    return latest


class FindingsBook:
    """The findings read last, the verdict history, and their :attr:`view`.

    The view is kept up to date at the cost of what changed (issue 38 item 2: rebuilt
    whole, 2,000 loops' first verdicts with 6,000 findings held the event loop 10 s): each
    finding's verdict is kept, and when the history says a loop's answers may have changed
    (:attr:`VerdictHistory.changed`) only that loop's findings are compared again and the
    counts moved; reading a file (:meth:`apply`) compares every finding once."""

    def __init__(self, history: VerdictHistory | None = None) -> None:
        self.history = history if history is not None else VerdictHistory()
        self.findings: tuple[Finding, ...] = ()
        self.source: str | None = None
        self.problems: tuple[str, ...] = ()  # of the last read
        self.view = FindingsView()
        self.verdicts: list[str] = []  # per finding, the verdict on its day
        self._of_loop: dict[str, list[int]] = {}  # loop -> its findings' indices
        self._counts: dict[tuple[str, str], int] = {}

    def apply(self, read: FindingsFile | None) -> bool:
        """Take a read file (None: no findings configured). A file that could not be read
        at all keeps the findings there were; returns whether the findings changed."""
        self.problems = () if read is None else read.problems
        if read is not None and not read.readable:
            self._publish()
            return False
        findings = () if read is None else read.findings
        changed = findings != self.findings
        self.findings, self.source = findings, None if read is None else read.source
        self._of_loop = {}
        for k, f in enumerate(findings):
            self._of_loop.setdefault(f.loop, []).append(k)
        self.history.changed.clear()
        self.verdicts = [self.history.verdict_on(f.loop, f.date) for f in findings]
        self._counts = {}
        for f, verdict in zip(findings, self.verdicts, strict=True):
            self._counts[verdict, f.finding] = self._counts.get((verdict, f.finding), 0) + 1
        self._publish(latest_of(findings))
        return changed

    def record(self, loop: str, t: float, verdict: str) -> None:
        self.history.record(loop, t, verdict)
        if self.history.changed:
            self.refresh()

    def refresh(self, *, force: bool = False) -> None:
        """Compare again the findings of the loops whose history changed (``force``: every
        loop's, e.g. after the history was loaded)."""
        loops = (list(self._of_loop) if force else
                 [lp for lp in self.history.changed if lp in self._of_loop])
        self.history.changed.clear()
        moved = False
        for loop in loops:
            for k in self._of_loop[loop]:
                f = self.findings[k]
                old, new = self.verdicts[k], self.history.verdict_on(loop, f.date)
                if old == new:
                    continue
                self.verdicts[k] = new
                self._counts[old, f.finding] -= 1
                if not self._counts[old, f.finding]:
                    del self._counts[old, f.finding]
                self._counts[new, f.finding] = self._counts.get((new, f.finding), 0) + 1
                moved = True
        if moved or force or self.view.problems != len(self.problems):
            self._publish()

    def _publish(self, latest: Mapping[str, Finding] | None = None) -> None:
        """A new immutable view (the latest findings shared: they change only with the
        file)."""
        self.view = FindingsView(self.view.latest if latest is None else latest,
                                 dict(self._counts), len(self.problems))

    def compared(self) -> list[tuple[Finding, str]]:
        """Every finding with the verdict its loop had on its day, in file order."""
        return list(zip(self.findings, self.verdicts, strict=True))


def finding_kinds() -> tuple[str, ...]:
    """The ``finding`` label's values: :data:`FINDINGS` and ``none``."""
    return (*FINDINGS, "none")
