"""One polling task per device: reads on a fixed schedule into the loop windows.

Each tick (every ``poll_interval_s / time_scale`` wall seconds, on an absolute schedule, so
no drift) reads every point of the device once and appends one sample per loop to its
window bank(s). A failed read appends a gap (NaN, quality NO_COMM), never a zero. Ticks
missed because a read overran are not made up in a burst: each is recorded as a gap row
(counted in ``missed_ticks``), so a window keeps one row per sample time.

Faults (docs/reliability.md):

* A device that cannot be reached, drops the connection or stops answering is closed and
  reconnected forever with capped, full-jitter exponential backoff
  (:class:`~gateway.backoff.Backoff`, cap ``gateway.reconnect_max_s``); the backoff is
  reset only by a successful read, so a device that accepts TCP but never answers is
  retried no faster than one that refuses. One log line when the device goes down, one
  when it recovers; ``stiction_device_up`` follows.
* A device that answers one block with a Modbus exception keeps its other points; the
  points of that block are gaps (NO_COMM), and one line is logged when the block starts
  failing and one when it answers again.
* Every connect and read runs under a hard time limit (:attr:`DevicePoller.guard_s`), so
  a misbehaving adapter cannot hang the tick.
* Values are checked for plausibility for every protocol: NaN/inf, a subnormal float (almost
  always a word-swapped float32) and a value outside the point's configured ``range`` are
  BAD samples (NaN in the window), logged once per change of the set of bad points.

A loop is *stale* (verdict code 6) when it has had no fresh sample - one the device
actually delivered, good or bad - for ``STALE_POLLS`` polls. Bad values from a device that
answers are not stale: they reach the analysis, which says ``bad_data`` and why.

Each completed tick updates :attr:`DevicePoller.last_progress`; the systemd watchdog only
pings while every poller keeps making progress (:meth:`DevicePoller.stalled`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import time

import numpy as np
from numpy.typing import NDArray

from ..config import DeviceConfig
from ..core.store import ResultStore
from ..core.ticks import Backoff
from ..core.windows import WindowBank
from ..errors import DeviceError
from ..inputs.base import DeviceInput, PointSpec, Quality, ReadResult
from ..outputs.prometheus.collector import GatewayMetrics

__all__ = ["BankSlot", "DevicePoller", "ProcessClock"]

log = logging.getLogger("gateway.poller")

STALE_POLLS = 3
BACKOFF_CAP_S = 30.0
BACKOFF_BASE_S = 0.5
FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # smallest normal float32


@dataclasses.dataclass(frozen=True)
class ProcessClock:
    """Process time: Unix time at ``time_scale`` 1, else start + elapsed × time_scale."""

    time_scale: float = 1.0
    start: float = dataclasses.field(default_factory=time.time)

    def now(self, wall: float | None = None) -> float:
        wall = time.time() if wall is None else wall
        return self.start + (wall - self.start) * self.time_scale


@dataclasses.dataclass(frozen=True)
class BankSlot:
    """A window bank fed by a device: per column the positions of its OP and PV in the
    device's point list, and its loop index in the result store."""

    bank: WindowBank
    op_points: NDArray[np.intp]
    pv_points: NDArray[np.intp]
    loops: NDArray[np.intp]


class DevicePoller:
    def __init__(self, device: DeviceConfig, adapter: DeviceInput, slots: list[BankSlot], *,
                 store: ResultStore, metrics: GatewayMetrics | None, clock: ProcessClock,
                 n_points: int, points: list[PointSpec] | None = None,
                 backoff: Backoff | None = None) -> None:
        self.device = device
        self.adapter = adapter
        self.slots = slots
        self.store = store
        self.metrics = metrics
        self.clock = clock
        self.period = device.poll_interval_s / clock.time_scale
        self.n_points = n_points
        self.points = list(points) if points is not None else []
        lo = np.full(n_points, -np.inf)
        hi = np.full(n_points, np.inf)
        for i, p in enumerate(self.points):
            if p.range is not None:
                lo[i], hi[i] = p.range
        self._lo, self._hi = lo, hi
        self.loops = (np.concatenate([s.loops for s in slots]) if slots
                      else np.zeros(0, dtype=np.intp))
        self.backoff = backoff or Backoff(min(BACKOFF_BASE_S, BACKOFF_CAP_S), 2.0,
                                          BACKOFF_CAP_S)
        # a hard limit on one connect or read, whatever the adapter does with its timeout
        self.guard_s = 10.0 * device.timeout_s + 1.0
        self.connected = False
        self.up: bool | None = None  # None until the first poll decided
        self.retry_at = 0.0
        self.polls = 0
        self.good_polls = 0
        self.missed_ticks = 0
        self.reconnects = 0  # successful connects after the first
        self.tick_starts: list[float] = []  # loop.time() of recent poll starts (jitter)
        self.last_progress: float | None = None  # loop.time() when the last tick ended
        self.next_due: float | None = None  # loop.time() of the next tick (for hand-over)
        self.failing_blocks: set[str] = set()
        self.bad_points: frozenset[int] = frozenset()
        self._connects = 0
        self._stop = asyncio.Event()
        self.first_tick = asyncio.Event()  # set when the first tick has completed
        self.phase_ref: float | None = None  # loop.time() instant on the tick grid, if set
        self._last_fresh = np.full(len(store.loops), -1, dtype=np.int64)

    # ------------------------------------------------------------------ lifecycle

    def take_over(self, old: DevicePoller) -> None:
        """Continue ``old``'s connection state (same device, same adapter) after a reload."""
        self.connected, self.up, self.retry_at = old.connected, old.up, old.retry_at
        self.backoff = old.backoff
        self._connects = old._connects
        self.failing_blocks = set(old.failing_blocks)

    def request_stop(self) -> None:
        """Make :meth:`run` return after the current tick (or at once while it sleeps).

        Shutdown and reload ask rather than cancel: cancelling a task inside a pymodbus
        request can leave it waiting forever (seen with pymodbus 3.16 on Python 3.11)."""
        self._stop.set()

    stop = request_stop

    def resume(self) -> None:
        """Undo :meth:`request_stop` so :meth:`run` can be started again."""
        self._stop.clear()

    def stalled(self, now: float) -> bool:
        """True when no tick has ended for longer than a tick can legitimately take."""
        if self.last_progress is None:
            return False
        return now - self.last_progress > self.period + 2 * self.guard_s + 1.0

    async def run(self, due: float | None = None) -> None:
        """Poll until :meth:`request_stop` (or cancellation); ``due`` is the loop time of
        the first tick (default now), so a reload continues its predecessor's schedule.
        The adapter is not closed here: its owner closes it (it may outlive a reload)."""
        loop = asyncio.get_running_loop()
        if due is None:
            due = loop.time()
            if self.phase_ref is not None:  # first tick on the grid phase_ref + n * period
                due = self.phase_ref + math.ceil((due - self.phase_ref) / self.period) \
                    * self.period
        self.last_progress = loop.time()
        while not self._stop.is_set():
            self.next_due = due
            delay = due - loop.time()
            if delay > 0:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._stop.wait(), delay)
                if self._stop.is_set():
                    break
            # ticks whose time has passed while the previous one overran are recorded as
            # gap rows before this tick's sample, so rows stay in time order
            behind = loop.time() - due
            if behind >= self.period:
                skip = int(behind // self.period)
                self.missed_ticks += skip
                due += skip * self.period
                for _ in range(min(skip, self._max_rows())):
                    self._gap(self.clock.now())
            self._note_start(loop.time())
            try:
                await self.poll_once()
            except Exception:  # a bug in one tick must not end polling for months
                log.exception("device %s: poll failed unexpectedly", self.device.name)
                await self._disconnect()
            self.last_progress = loop.time()
            self.first_tick.set()
            due += self.period
        self.next_due = due

    def _max_rows(self) -> int:
        return max((s.bank.size for s in self.slots), default=0)

    def _note_start(self, t: float) -> None:
        self.tick_starts.append(t)
        if len(self.tick_starts) > 4096:
            del self.tick_starts[:2048]

    async def _disconnect(self) -> None:
        self.connected = False
        with contextlib.suppress(Exception):
            await self.adapter.close()

    # ------------------------------------------------------------------ one tick

    async def poll_once(self) -> None:
        """One tick: (re)connect if needed, read, append one sample per loop."""
        loop = asyncio.get_running_loop()
        wall = time.time()
        t_proc = self.clock.now(wall)
        self.polls += 1
        name = self.device.name
        if not self.connected:
            if loop.time() < self.retry_at:
                self._gap(t_proc)
                return
            try:
                async with asyncio.timeout(self.guard_s):
                    await self.adapter.connect()
            except TimeoutError:
                self._failed(DeviceError(name, "timeout",
                                         f"connect took over {self.guard_s:g} s"), loop.time())
                await self._disconnect()
                self._gap(t_proc)
                return
            except DeviceError as exc:
                self._failed(exc, loop.time())
                self._gap(t_proc)
                return
            self.connected = True
            self._connects += 1
            if self._connects > 1:
                self.reconnects += 1
        t0 = time.perf_counter()
        try:
            async with asyncio.timeout(self.guard_s):
                result = await self.adapter.read()
        except (DeviceError, TimeoutError) as exc:
            self._failed(exc if isinstance(exc, DeviceError) else DeviceError(
                name, "timeout", f"read took over {self.guard_s:g} s"), loop.time())
            await self._disconnect()
            self._gap(t_proc)
            return
        if self.metrics is not None:
            self.metrics.poll_duration.labels(device=name).observe(time.perf_counter() - t0)
            self.metrics.poll_requests.labels(device=name).inc(result.requests)
            for block_err in result.errors:
                self.metrics.poll_errors.labels(device=name, kind=block_err.kind).inc()
        self._note_blocks(result)
        if self.up is not True:
            if self.up is False:
                log.warning("device %s: recovered", name)
            self.up = True
            if self.metrics is not None:
                self.metrics.device_up.labels(device=name).set(1)
        self.backoff.reset()
        self.good_polls += 1
        values, quality = self._check_values(result.values.copy(), result.quality.copy())
        self._append(t_proc, values, quality)

    def _failed(self, exc: DeviceError, now: float) -> None:
        if self.metrics is not None:
            self.metrics.poll_errors.labels(device=self.device.name, kind=exc.kind).inc()
            self.metrics.device_up.labels(device=self.device.name).set(0)
        if self.up is not False:
            log.warning("device %s: down (%s): %s; retrying with backoff up to %g s",
                        self.device.name, exc.kind, exc, self.backoff.cap)
        self.up = False
        self.retry_at = now + self.backoff.next_delay()

    def _note_blocks(self, result: ReadResult) -> None:
        """Log once when a block starts failing (e.g. a Modbus exception) and once when it
        answers again."""
        failing = {_block_key(e) for e in result.errors}
        if failing == self.failing_blocks:
            return
        name = self.device.name
        for key in sorted(failing - self.failing_blocks):
            msg = next(str(e) for e in result.errors if _block_key(e) == key)
            log.warning("%s; its points are gaps until it answers", msg)
        for key in sorted(self.failing_blocks - failing):
            log.warning("device %s: %s answering again", name, key)
        self.failing_blocks = failing

    def _check_values(self, values: NDArray[np.float64], quality: NDArray[np.uint8]
                      ) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
        """Flag implausible values BAD (NaN in the window): non-finite, subnormal (a
        word-swapped float32, nearly always) or outside the point's ``range``."""
        with np.errstate(invalid="ignore"):
            mag = np.abs(values)
            implausible = (~np.isfinite(values) | ((mag < FLOAT32_TINY) & (mag > 0))
                           | (values < self._lo) | (values > self._hi))
        flag = implausible & (quality == Quality.GOOD)
        quality[flag] = Quality.BAD
        values[quality != Quality.GOOD] = np.nan
        bad = frozenset(np.flatnonzero(quality == Quality.BAD).tolist())
        if bad != self.bad_points:
            if bad:
                names = [self._point_name(i) for i in sorted(bad)]
                more = f" and {len(names) - 5} more" if len(names) > 5 else ""
                log.warning("device %s: bad values (NaN, inf, subnormal or out of range) "
                            "at %s%s", self.device.name, ", ".join(names[:5]), more)
            else:
                log.warning("device %s: values plausible again", self.device.name)
            self.bad_points = bad
        return values, quality

    def _point_name(self, i: int) -> str:
        if i < len(self.points):
            return f"{self.points[i].loop}.{self.points[i].role}"
        return f"point {i}"

    def _gap(self, t_proc: float) -> None:
        values = np.full(self.n_points, np.nan)
        quality = np.full(self.n_points, Quality.NO_COMM, dtype=np.uint8)
        self._append(t_proc, values, quality)

    def _append(self, t_proc: float, values: NDArray[np.float64],
                quality: NDArray[np.uint8]) -> None:
        st = self.store
        for s in self.slots:
            op, pv = values[s.op_points], values[s.pv_points]
            q = np.maximum(quality[s.op_points], quality[s.pv_points])
            s.bank.append(t_proc, op, pv, q)
            st.latest_op[s.loops] = op
            st.latest_pv[s.loops] = pv
            fresh = q < Quality.NO_COMM  # delivered by the device, good or not
            self._last_fresh[s.loops[fresh]] = self.polls
        last = self._last_fresh[self.loops]
        st.set_stale(self.loops, (last < 0) & (self.polls > STALE_POLLS)
                     | (last >= 0) & (self.polls - last >= STALE_POLLS))


def _block_key(err: DeviceError) -> str:
    """``holding 100+4`` from ``device X: holding 100+4: exception code 2``."""
    text = str(err)
    prefix = f"device {err.device}: "
    text = text.removeprefix(prefix)
    return text.split(": ", 1)[0]
