"""Analysis workers run niced, so polling wins a contested core (issue 8)."""

from __future__ import annotations

import asyncio
import os

from gateway.core.store import ResultStore
from gateway.runtime.scheduler import WORKER_NICE, AnalysisScheduler


def _worker_niceness(nice: int) -> tuple[int, int]:
    async def go() -> int:
        sched = AnalysisScheduler([], ResultStore([]), interval_wall_s=1e9, workers=1, nice=nice)
        await sched.start()
        try:
            assert sched._pool is not None
            return await asyncio.get_running_loop().run_in_executor(sched._pool, os.nice, 0)
        finally:
            await sched.stop()

    return os.nice(0), asyncio.run(go())


def test_workers_are_niced_by_default() -> None:
    parent, worker = _worker_niceness(WORKER_NICE)
    assert worker == min(19, parent + WORKER_NICE)


def test_nice_zero_keeps_the_parent_priority() -> None:
    parent, worker = _worker_niceness(0)
    assert worker == parent
