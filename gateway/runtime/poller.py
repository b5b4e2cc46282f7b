"""One polling task per device: the asyncio shell around the rules of :mod:`gateway.core`.

:meth:`DevicePoller.run` keeps the absolute tick schedule (:class:`~gateway.core.ticks.TickGrid`;
ticks missed because a poll overran become gap rows at their own due times, counted in
``missed_ticks`` and ``stiction_poll_missed_ticks_total``; how late each poll starts goes to
``stiction_poll_lateness_seconds``; a device that cannot keep its interval is flagged,
:class:`~gateway.core.ticks.Lag` (a tenth of its ticks missed within a minute),
``stiction_device_behind_schedule``, one log line each way, and its loops go stale as for
any tick without a sample) and calls
:meth:`DevicePoller.tick`, which reads the clocks once and does one poll: (re)connect when
the :class:`~gateway.core.ticks.Link` allows it, read under a hard time limit, turn raw
values into engineering values (:class:`~gateway.core.points.PointTable`), append one sample
per loop to the windows and update the stale flags. A failed read appends a gap (NaN,
NO_COMM), never a zero.

The poller is the one owner of reconnecting: a device that cannot be reached, drops the
connection or stops answering is closed and tried again forever with capped, full-jitter
exponential backoff (cap ``gateway.reconnect_max_s``, longer after a refused login), reset
only by a successful read. One log line when a device goes down, one when it recovers; the
same for a failing block (e.g. a Modbus exception) and for the set of implausible points.

Each completed tick updates :attr:`DevicePoller.last_progress`; the systemd watchdog only
pings while every poller keeps making progress (:meth:`DevicePoller.stalled`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..config.model import DeviceConfig
from ..core.points import Implausible, PointSpec, PointTable, Quality, explain
from ..core.store import ResultStore
from ..core.ticks import (
    Backoff,
    Lag,
    Link,
    ProcessClock,
    SetTracker,
    StaleTracker,
    TickGrid,
    missed_times,
    stalled,
)
from ..core.windows import LoopGroup, record
from ..errors import DeviceError
from ..inputs.base import ReadResult, Source
from ..outputs.prometheus import GatewayMetrics

__all__ = ["BACKOFF_BASE_S", "Clocks", "DevicePoller", "all_refused"]

log = logging.getLogger("gateway.poller")

BACKOFF_BASE_S = 0.5
IMPLAUSIBLE_EXPLAINED = 3
"""Points whose implausible value a log line explains (the others are only named)."""


@dataclasses.dataclass(frozen=True)
class Clocks:
    """Where a poller reads the time: ``mono`` (the event loop's clock, for schedules and
    backoff), ``wall`` (Unix seconds, for samples) and ``perf`` (durations). Tests pass
    their own."""

    mono: Callable[[], float]
    wall: Callable[[], float] = time.time
    perf: Callable[[], float] = time.perf_counter


class DevicePoller:
    def __init__(self, device: DeviceConfig, source: Source, groups: Sequence[LoopGroup],
                 points: Sequence[PointSpec], *, store: ResultStore,
                 metrics: GatewayMetrics | None, clock: ProcessClock,
                 backoff: Backoff | None = None, clocks: Clocks | None = None) -> None:
        self.device = device
        self.source = source
        self.groups = list(groups)
        self.store = store
        self.metrics = metrics
        self.clock = clock
        self.clocks = clocks
        self.period = device.poll_interval_s / clock.time_scale
        self.grid = TickGrid(self.period)
        self.table = PointTable(points)
        self.loops = (np.concatenate([g.rows for g in self.groups]) if self.groups
                      else np.zeros(0, dtype=np.intp))
        self.link = Link(backoff or Backoff(BACKOFF_BASE_S, 2.0, 30.0))
        self.stale = StaleTracker(len(self.loops))
        self.report = DeviceReport(device.name, metrics, self.period,
                                   device.poll_interval_s)
        # a hard limit on one connect or read, whatever the source does with its timeout
        self.guard_s = 10.0 * device.timeout_s + 1.0
        self.connected = False
        self.down_reason: str | None = None  # why the device is down (None while up)
        self.polls = self.good_polls = self.missed_ticks = 0
        self.ticks = 0  # polls and missed ticks: the stale flags count both
        self.reconnects = 0  # successful connects after the first
        self._connects = 0
        self.tick_starts: list[float] = []  # clocks.mono() of recent tick starts (jitter)
        self.last_progress: float | None = None  # clocks.mono() when the last tick ended
        self.next_due: float | None = None  # clocks.mono() of the next tick (for hand-over)
        self._stop = asyncio.Event()
        self.first_tick = asyncio.Event()  # set when the first tick has completed

    @property
    def up(self) -> bool | None:
        return self.link.up

    @property
    def backoff(self) -> Backoff:
        return self.link.backoff

    def take_over(self, old: DevicePoller) -> None:
        """Continue ``old``'s connection state (same device, same source) after a reload."""
        self.connected, self.link = old.connected, old.link
        self.down_reason = old.down_reason
        self.report.take_over(old.report)
        self._connects = old._connects

    def request_stop(self) -> None:
        """Make :meth:`run` return after the current tick (or at once while it sleeps).

        Shutdown and reload ask rather than cancel: cancelling a task inside a pymodbus
        request can leave it waiting forever (seen with pymodbus 3.16 on Python 3.11)."""
        self._stop.set()

    def resume(self) -> None:
        """Undo :meth:`request_stop` so :meth:`run` can be started again."""
        self._stop.clear()

    def stalled(self, now: float) -> bool:
        return stalled(now, self.last_progress, self.period, self.guard_s)

    def _mono(self) -> Callable[[], float]:
        if self.clocks is None:
            self.clocks = Clocks(asyncio.get_running_loop().time)
        return self.clocks.mono

    async def run(self, due: float | None = None) -> None:
        """Poll until :meth:`request_stop`; ``due`` is the loop time of the first tick
        (default: now, or the grid's next tick), so a reload keeps its predecessor's
        schedule. The source is not closed here: its owner closes it (it may outlive a
        reload)."""
        mono = self._mono()
        if due is None:
            due = self.grid.first_due(mono())
        self.last_progress = mono()
        while not self._stop.is_set():
            self.next_due = due
            delay = due - mono()
            if delay > 0:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._stop.wait(), delay)
                if self._stop.is_set():
                    break
            now = mono()
            missed, due = self.grid.catch_up(due, now)
            self._schedule(due, missed, now)
            try:
                await self.tick()
            except Exception:  # a bug in one tick must not end polling for months
                log.exception("device %s: poll failed unexpectedly", self.device.name)
                await self._disconnect()
            self.last_progress = mono()
            self.first_tick.set()
            due += self.period
        self.next_due = due

    def _schedule(self, due: float, missed: int, now: float) -> None:
        """Record the ``missed`` ticks before ``due`` as gap rows at their own times, and
        report how late this tick starts."""
        assert self.clocks is not None
        wall = self.clocks.wall()
        rows = max((g.bank.size for g in self.groups), default=0)
        self.missed_ticks += missed
        self.ticks += max(0, missed - rows)
        for t_due in missed_times(due - missed * self.period, missed, self.period, rows):
            self.ticks += 1
            self._gap(self.clock.now(wall - (now - t_due)))
        self.report.schedule(missed, now - due, now, up=self.link.up is True)

    async def _disconnect(self) -> None:
        self.connected = False
        with contextlib.suppress(Exception):
            await self.source.close()

    # ------------------------------------------------------------------ one tick

    async def tick(self) -> None:
        """One poll: (re)connect if due, read, append one sample per loop."""
        mono = self._mono()
        clocks = self.clocks
        assert clocks is not None
        self.tick_starts.append(mono())
        if len(self.tick_starts) > 4096:
            del self.tick_starts[:2048]
        t_proc = self.clock.now(clocks.wall())
        self.polls += 1
        self.ticks += 1
        if not self.connected:
            if not self.link.may_connect(mono()):
                self._gap(t_proc)
                return
            try:
                async with asyncio.timeout(self.guard_s):
                    await self.source.connect()
            except (DeviceError, TimeoutError) as exc:
                self._failed(exc, "connect")
                await self._disconnect()
                self._gap(t_proc)
                return
            self.connected = True
            self._connects += 1
            if self._connects > 1:
                self.reconnects += 1
        t0 = clocks.perf()
        try:
            async with asyncio.timeout(self.guard_s):
                result = await self.source.read()
        except (DeviceError, TimeoutError) as exc:
            self._failed(exc, "read")
            await self._disconnect()
            self._gap(t_proc)
            return
        refused = all_refused(result)
        if refused is not None:  # it answers, but serves nothing: down, with the reason
            self.report.refused(result.errors)
            self._failed(refused, "read")
            self._gap(t_proc)
            return
        self._answered(result, clocks.perf() - t0)
        values, quality, causes = self.table.judge(result.values, result.quality)
        self.report.bad_points(causes, result.values, self.table)
        self._append(t_proc, values, quality)

    def _failed(self, exc: DeviceError | TimeoutError, what: str) -> None:
        name = self.device.name
        err = exc if isinstance(exc, DeviceError) else DeviceError(
            name, "timeout", f"{what} took over {self.guard_s:g} s")
        self.report.failed(err)
        went_down = self.link.failed(err.kind, self._mono()())
        if went_down or err.reason != self.down_reason:  # the outage, or its new cause
            again = ("polling on; its loops are device_down" if err.kind == "exception" else
                     f"retrying with backoff up to {self.link.backoff.cap_for(err.kind):g} s")
            log.warning("device %s: %s (%s): %s; %s", name, "down" if went_down else
                        "still down, now", err.reason, err, again)
        self.down_reason = err.reason

    def _answered(self, result: ReadResult, seconds: float) -> None:
        self.report.answered(result, seconds)
        before = self.link.answered()
        self.down_reason = None
        if before is False:
            log.warning("device %s: recovered", self.device.name)
        if before is not True:
            self.report.up()
        self.good_polls += 1

    def _gap(self, t_proc: float) -> None:
        self._append(t_proc, *self.table.gap())

    def _append(self, t_proc: float, values: np.ndarray, quality: np.ndarray) -> None:
        fresh = record(self.groups, t_proc, values, quality, self.store)
        self.store.set_stale(self.loops, self.stale.update(self.ticks, fresh),
                             down=self.link.up is False)


class DeviceReport:
    """What a device's polls tell the operator: its metrics (``metrics`` may be None) and
    its log lines, one per change: a block failing or answering again, the set of
    implausible points, the device falling behind its schedule or catching up."""

    def __init__(self, name: str, metrics: GatewayMetrics | None, period: float,
                 interval_s: float) -> None:
        self.name, self.metrics, self.interval_s = name, metrics, interval_s
        self.blocks = SetTracker()  # failing blocks ("holding 100+4")
        self.bad = SetTracker()  # points with implausible values
        self.lag = Lag(period)
        self._behind(False)  # a new poller starts on schedule (a reload rebuilds it)

    def take_over(self, old: DeviceReport) -> None:
        """Go on with ``old``'s failing blocks and, at the same interval, its schedule."""
        self.blocks = old.blocks
        if old.lag.period == self.lag.period:
            self.lag = old.lag
            self._behind(self.lag.behind)

    def _behind(self, behind: bool) -> None:
        if self.metrics is not None:
            self.metrics.behind.labels(device=self.name).set(1 if behind else 0)

    def schedule(self, missed: int, late: float, now: float, *, up: bool) -> None:
        """A tick starts ``late`` s after it was due, ``missed`` ticks after the last; a
        device that is not ``up`` (reported down already) is not judged."""
        m = self.metrics
        if m is not None:
            m.missed_ticks.labels(device=self.name).inc(missed)
            m.poll_lateness.labels(device=self.name).observe(max(0.0, late))
        change = self.lag.update(now, missed) if up else None
        if change is None:
            return
        self._behind(change)
        if change:
            log.warning("device %s: polls cannot keep poll_interval_s (%g s): %d of the "
                        "last %d ticks missed (their samples are gaps)", self.name,
                        self.interval_s, self.lag.missed, round(self.lag.ticks(now)))
        else:
            log.warning("device %s: polls keep their schedule again", self.name)

    def failed(self, err: DeviceError) -> None:
        """The device is down (again): ``stiction_device_up`` 0, and why, in the words of
        the log line (``stiction_device_down_reason``); not also behind schedule (one fault,
        one alert): its schedule is judged afresh once it answers again."""
        if self.lag.behind:
            self.lag = Lag(self.lag.period, self.lag.window_s)
            self._behind(False)
        if self.metrics is not None:
            self.metrics.poll_errors.labels(device=self.name, kind=err.kind).inc()
            self.metrics.device_up.labels(device=self.name).set(0)
            self.metrics.set_down_reason(self.name, err.reason)

    def up(self) -> None:
        if self.metrics is not None:
            self.metrics.device_up.labels(device=self.name).set(1)
            self.metrics.set_down_reason(self.name, None)

    def refused(self, errors: Sequence[DeviceError]) -> None:
        """Count the requests the device refused, by the refusal's words."""
        if self.metrics is not None:
            for err in errors:
                if err.kind == "exception":
                    self.metrics.count_refused(self.name, err.reason)

    def answered(self, result: ReadResult, seconds: float) -> None:
        m = self.metrics
        self.refused(result.errors)
        if m is not None:
            m.poll_duration.labels(device=self.name).observe(seconds)
            m.poll_requests.labels(device=self.name).inc(result.requests)
            for block_err in result.errors:
                m.poll_errors.labels(device=self.name, kind=block_err.kind).inc()
        messages = {_block_key(e): str(e) for e in result.errors}
        came, went = self.blocks.update(messages)
        for key in came:
            log.warning("%s; its points are gaps until it answers", messages[str(key)])
        for key in went:
            log.warning("device %s: %s answering again", self.name, key)

    def bad_points(self, causes: np.ndarray, raw: np.ndarray, table: PointTable) -> None:
        """One line when the set of points with implausible values (``causes``, one
        :class:`~gateway.core.points.Implausible` per point) changes: the points, and for
        the first few the value and its likely cause, in ``probe``'s words."""
        bad = np.flatnonzero(causes != Implausible.NONE).tolist()
        came, went = self.bad.update(bad)
        if not came and not went:
            return
        if not bad:
            log.warning("device %s: values plausible again", self.name)
            return
        why = "; ".join(f"{_point_name(table.points[i])}: "
                        f"{explain(table.points[i], float(raw[i]), int(causes[i]))}"
                        for i in bad[:IMPLAUSIBLE_EXPLAINED])
        more = len(bad) - IMPLAUSIBLE_EXPLAINED
        log.warning("device %s: implausible values at %s (bad samples until they are "
                    "plausible) - %s%s", self.name, table.names(bad), why,
                    f"; and {more} more point(s)" if more > 0 else "")


def all_refused(result: ReadResult) -> DeviceError | None:
    """A read the device answered by refusing every point (each request a protocol
    exception, e.g. Modbus exception 10 for a unit id it does not serve) as one
    DeviceError of kind ``exception``: the device is down for the gateway, with the
    refusal's reason; None for any other read."""
    errors = result.errors
    if not errors or any(e.kind != "exception" for e in errors) \
            or not (result.quality == Quality.NO_COMM).all():
        return None
    first = errors[0]
    reasons = {e.reason for e in errors}
    reason = first.reason if len(reasons) == 1 else DeviceError.REASONS["exception"]
    text = str(first).removeprefix(f"device {first.device}: ")
    if len(errors) > 1:
        text = f"all {len(errors)} requests refused, the first: {text}"
    return DeviceError(first.device, "exception", text, reason=reason)


def _point_name(p: PointSpec) -> str:
    """``FIC101 op (loops.csv: line 4)``."""
    return f"{p.loop} {p.role}" + (f" ({p.origin})" if p.origin else "")


def _block_key(err: DeviceError) -> str:
    """``holding 100+4`` from ``device X: holding 100+4: exception code 2``."""
    return str(err).removeprefix(f"device {err.device}: ").split(": ", 1)[0]
