"""One polling task per device: reads on a fixed schedule into the loop windows.

Each tick (every ``poll_interval_s / time_scale`` wall seconds, on an absolute schedule, so
no drift) reads every point of the device once and appends one sample per loop to its
window bank(s). A failed read appends a gap (NaN, quality NO_COMM), never a zero. A device
that fails is closed and reconnected with capped, jittered exponential backoff; the first
failure and the recovery are logged once each. Ticks missed because a read overran are
skipped (counted in ``missed_ticks``), not made up in a burst.

A loop is *stale* when it has had no good sample for ``STALE_POLLS`` polls.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import math
import random
import time

import numpy as np
from numpy.typing import NDArray

from .config import DeviceConfig
from .errors import DeviceError
from .inputs.base import DeviceInput, Quality
from .metrics import GatewayMetrics
from .store import ResultStore
from .windows import WindowBank

__all__ = ["BankSlot", "DevicePoller", "ProcessClock"]

log = logging.getLogger(__name__)

STALE_POLLS = 3
BACKOFF_CAP_S = 30.0


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
                 n_points: int) -> None:
        self.device = device
        self.adapter = adapter
        self.slots = slots
        self.store = store
        self.metrics = metrics
        self.clock = clock
        self.period = device.poll_interval_s / clock.time_scale
        self.n_points = n_points
        self.loops = (np.concatenate([s.loops for s in slots]) if slots
                      else np.zeros(0, dtype=np.intp))
        self.connected = False
        self.up: bool | None = None  # None until the first poll decided
        self.attempt = 0
        self.retry_at = 0.0
        self.polls = 0
        self.good_polls = 0
        self.missed_ticks = 0
        self.tick_starts: list[float] = []  # loop.time() of recent poll starts (jitter)
        self._last_good = np.full(len(store.loops), -1, dtype=np.int64)
        self._stop = asyncio.Event()
        self.phase_ref: float | None = None  # loop.time() instant on the tick grid, if set

    def stop(self) -> None:
        """Finish the poll in progress (if any) and return from :meth:`run`.

        Shutdown asks rather than cancels: cancelling a task inside a pymodbus request
        can leave it waiting forever (seen with pymodbus 3.16 on Python 3.11)."""
        self._stop.set()

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        due = loop.time()
        if self.phase_ref is not None:  # first tick on the grid phase_ref + n * period
            due = self.phase_ref + math.ceil((due - self.phase_ref) / self.period) * self.period
        try:
            while not self._stop.is_set():
                delay = due - loop.time()
                if delay > 0:
                    with contextlib.suppress(TimeoutError):
                        await asyncio.wait_for(self._stop.wait(), delay)
                    if self._stop.is_set():
                        break
                self._note_start(loop.time())
                await self.poll_once()
                due += self.period
                behind = loop.time() - due
                if behind > self.period:
                    skip = int(behind // self.period)
                    self.missed_ticks += skip
                    due += skip * self.period
        finally:
            await self.adapter.close()

    def _note_start(self, t: float) -> None:
        self.tick_starts.append(t)
        if len(self.tick_starts) > 4096:
            del self.tick_starts[:2048]

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
                await self.adapter.connect()
                self.connected = True
            except DeviceError as exc:
                self._failed(exc, loop.time())
                self._gap(t_proc)
                return
        t0 = time.perf_counter()
        try:
            result = await self.adapter.read()
        except DeviceError as exc:
            self._failed(exc, loop.time())
            await self.adapter.close()
            self.connected = False
            self.retry_at = 0.0  # first reconnect at the next tick, then back off
            self._gap(t_proc)
            return
        if self.metrics is not None:
            self.metrics.poll_duration.labels(device=name).observe(time.perf_counter() - t0)
            self.metrics.poll_requests.labels(device=name).inc(result.requests)
            for err in result.errors:
                self.metrics.poll_errors.labels(device=name, kind=err.kind).inc()
        if self.up is not True:
            if self.up is False:
                log.warning("device %s: recovered", name)
            self.up = True
            self.attempt = 0
            if self.metrics is not None:
                self.metrics.device_up.labels(device=name).set(1)
        self.good_polls += 1
        self._append(t_proc, result.values, result.quality)

    def _failed(self, exc: DeviceError, now: float) -> None:
        if self.metrics is not None:
            self.metrics.poll_errors.labels(device=self.device.name, kind=exc.kind).inc()
            self.metrics.device_up.labels(device=self.device.name).set(0)
        if self.up is not False:
            log.warning("device %s: down (%s): %s", self.device.name, exc.kind, exc)
        self.up = False
        self.attempt += 1
        backoff = min(BACKOFF_CAP_S, 0.5 * 2.0 ** min(self.attempt, 10))
        self.retry_at = now + random.uniform(0.5, 1.0) * backoff

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
            good = s.loops[q == Quality.GOOD]
            self._last_good[good] = self.polls
        last = self._last_good[self.loops]
        st.set_stale(self.loops, (last < 0) & (self.polls > STALE_POLLS)
                     | (last >= 0) & (self.polls - last >= STALE_POLLS))
