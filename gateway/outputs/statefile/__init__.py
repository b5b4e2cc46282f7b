"""State file output (``gateway.state_file``): windows and latest assessments survive a
restart. :mod:`.format` writes and reads the file, :mod:`.restore` puts it back.

The sink restores the file when it starts (before any poll), writes it every
``gateway.persist_interval_s`` (a failing write is logged once, and once when it works
again: a full disk must not stop the gateway) and once more when it stops. With the
gateway's metrics it counts failed writes (``stiction_state_write_failures_total``), keeps
the time of the last good one (``stiction_state_last_write_timestamp_seconds``), counts
a file set aside at start (``stiction_state_file_set_aside_total{reason}``; ``unreadable``:
not restored, not set aside: not a regular file, or no answer from the file system within
``gateway.config.reading.STATE_READ_TIMEOUT_S``; it is read off the event loop) and says how far
the wall clock was behind the file's last write at start
(``stiction_state_clock_back_seconds``: it stepped back across the restart).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from typing import Any

from ..base import Binding, PeriodicWrites, in_thread
from .format import read_state, snapshot, write_state
from .restore import RestoreReport, apply_state, read_for_restore, restore_state

__all__ = ["RestoreReport", "StateFile", "create_sink", "read_state", "restore_state"]

log = logging.getLogger("gateway.state")


def create_sink(binding: Binding, *, metrics: Any = None, **_: Any) -> StateFile:
    return StateFile(binding, metrics=metrics)


class StateFile:
    """Restores on :meth:`start`, writes periodically and on :meth:`stop`."""

    def __init__(self, binding: Binding, *, wall: Callable[[], float] = time.time,
                 metrics: Any = None) -> None:
        self.binding = binding
        self.wall = wall
        self.metrics = metrics  # GatewayMetrics (duck-typed: a sink imports no other)
        self.failures = 0  # writes that failed
        self.saves = 0
        self.last_save_s = 0.0  # wall time the last write took
        self.report: RestoreReport | None = None
        # held by a write (its snapshot is a copy of the windows) and by a reload, which
        # makes new windows beside the old: never both copies at once (config/checks.py)
        self.exclusive = asyncio.Lock()
        self.writes = PeriodicWrites(
            "state file", lambda: self.path, self.save,
            lambda: self.binding.config.gateway.persist_interval_s, log=log,
            failed=self._failed)

    @property
    def path(self) -> str:
        return self.binding.config.gateway.state_file

    async def bind(self, binding: Binding) -> None:
        if binding.config.gateway.state_file != self.path:
            log.warning("reload: state is written to %s from now on (not restored)",
                        binding.config.gateway.state_file)
        self.binding = binding

    async def start(self) -> None:
        b = self.binding
        read = await asyncio.to_thread(read_for_restore, self.path, b.groups)  # bounded
        self.report = apply_state(read, self.path, b.config, b.groups, b.store,
                                  wall=self.wall(), time_scale=b.clock.time_scale)
        if self.metrics is not None:
            if self.report.kind is not None:
                self.metrics.state_set_aside.labels(reason=self.report.kind).inc()
            self.metrics.state_clock_back.set(self.report.clock_back_s)
        self.writes.start()

    async def save(self, *, final: bool = False) -> int:
        """Write the state file now (atomically); returns its size in bytes. ``final``: the
        last write before a normal exit (no assessment follows)."""
        async with self.exclusive:
            b = self.binding
            wall = self.wall()
            header, arrays = snapshot(b.config, b.groups, b.store, wall=wall,
                                      proc=b.clock.now(wall), clean=final)
            t0 = time.perf_counter()
            size = await in_thread(write_state, self.path, header, arrays)
            self.last_save_s = time.perf_counter() - t0
            self.saves += 1
            if self.metrics is not None:
                self.metrics.state_last_write.set(wall)
            log.debug("state file %s: %d bytes in %.3f s", self.path, size, self.last_save_s)
            return size

    async def stop(self) -> None:
        await self.writes.stop(final=True)

    def _failed(self) -> None:
        self.failures += 1
        if self.metrics is not None:
            self.metrics.state_write_failures.inc()
