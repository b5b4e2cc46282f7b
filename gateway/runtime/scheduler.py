"""Scheduled analysis in worker processes, so the event loop keeps polling on time.

Every ``analysis_interval_s`` process seconds (``/ time_scale`` wall seconds) one round
analyses every loop: windows are copied out of the ring buffers in batches of
``batch_size`` loops (one pickle per batch, not per loop), each batch runs
``stiction.analyze`` in a ``ProcessPoolExecutor`` worker (spawned, never forked from the
threaded gateway), and the results go into the :class:`~gateway.store.ResultStore`. At most
``2 × workers`` batches are in flight, which bounds the memory a round holds. A round that
is still running when the next is due makes that one wait (no pile-up). Workers run at a
lower CPU priority (``nice`` +10 by default), so on a busy box the polling event loop wins a
contested core and analysis only takes what is left.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import importlib
import logging
import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment, Verdict

from ..config import LoopConfig
from ..core.store import ResultStore
from ..core.windows import WindowBank, analysis_segment
from ..inputs.base import Quality

__all__ = ["AnalysisScheduler", "BankRef", "LoopJob", "analyze_batch"]

log = logging.getLogger("gateway.analysis")

DEFAULT_ANALYZE = "stiction:analyze"
WORKER_NICE = 10
"""Niceness added to each analysis worker: polling must keep its schedule under load."""


@dataclasses.dataclass(frozen=True)
class LoopJob:
    """What a worker needs to analyse one loop (picklable)."""

    index: int  # loop index in the store
    op: NDArray[np.float32]
    pv: NDArray[np.float32]
    quality: NDArray[np.uint8]
    size: int  # window length in samples (for the fill ratio)
    ts: float
    kp: float | None
    delay: float
    process: str
    op_range: tuple[float, float]


@dataclasses.dataclass(frozen=True)
class BankRef:
    """A window bank and, per column, the loop index in the store and its config."""

    bank: WindowBank
    loops: Sequence[int]
    configs: Sequence[LoopConfig]
    ts: float


_FUNCS: dict[str, Callable[..., Assessment]] = {}


def _resolve(path: str) -> Callable[..., Assessment]:
    fn = _FUNCS.get(path)
    if fn is None:
        module, _, name = path.partition(":")
        fn = getattr(importlib.import_module(module), name)
        _FUNCS[path] = fn
    return fn


def analyze_batch(path: str, jobs: Sequence[LoopJob]
                  ) -> list[tuple[int, Assessment, float, int, float]]:
    """Worker entry: (index, assessment, window fill, samples used, seconds) per job."""
    analyze = _resolve(path)
    out = []
    for job in jobs:
        t0 = time.perf_counter()
        fill = float(np.count_nonzero(job.quality == Quality.GOOD)) / job.size
        op, pv = analysis_segment(job.op, job.pv, job.quality)
        reason = bad_values_reason(job.quality, len(op))
        if reason is not None:
            a = Assessment(Verdict.BAD_DATA, reason)
        elif len(op) < 2:
            a = Assessment(Verdict.BAD_DATA, "no usable samples in the window yet")
        else:
            try:
                a = analyze(op, pv, ts=job.ts, kp=job.kp, delay=job.delay,
                            process=job.process, op_range=job.op_range)
            except Exception as exc:  # a bug in one window must not stop the round
                a = Assessment(Verdict.BAD_DATA, f"analysis failed: {type(exc).__name__}: {exc}")
        out.append((job.index, a, fill, len(op), time.perf_counter() - t0))
    return out


BAD_TAIL = 3  # trailing BAD samples beyond which the current data is called unusable
MIN_SEGMENT = 32  # stiction.analyze's minimum window


def bad_values_reason(quality: NDArray[np.uint8], usable: int) -> str | None:
    """Why a window is bad_data because the device delivered implausible values (quality
    BAD: NaN, inf, subnormal, outside the configured range), or None. Communication gaps
    are not reported here: they make the loop stale."""
    bad = quality == Quality.BAD
    n_bad = int(np.count_nonzero(bad))
    if n_bad == 0:
        return None
    what = "NaN, inf, subnormal (word-swapped?) or outside the configured range"
    tail = len(quality) - int(np.flatnonzero(~bad)[-1]) - 1 if not bad.all() else len(quality)
    if tail > BAD_TAIL:
        return f"the latest {tail} samples are bad values ({what})"
    if usable < MIN_SEGMENT:
        return (f"only {usable} usable samples since the last run of bad values "
                f"({n_bad} bad samples in the window: {what})")
    return None


def _init_worker(increment: int) -> None:
    """Worker initializer: ignore SIGINT and lower this process's CPU priority (never fails
    the worker). A Ctrl-C reaches every process of the terminal's group; the gateway handles
    it and stops the pool, so the workers must not die of it first (each printed a
    KeyboardInterrupt traceback after "demo stopped")."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if increment > 0:
        with contextlib.suppress(OSError, AttributeError):
            os.nice(increment)


def _warm(path: str) -> int:
    _resolve(path)
    return os.getpid()


class AnalysisScheduler:
    """Runs analysis rounds over ``banks`` and writes the results into ``store``."""

    def __init__(self, banks: Sequence[BankRef], store: ResultStore, *,
                 interval_wall_s: float, workers: int = 0, batch_size: int = 64,
                 analyze: str = DEFAULT_ANALYZE,
                 on_duration: Callable[[float], None] | None = None,
                 nice: int = WORKER_NICE) -> None:
        self.banks = list(banks)
        self.store = store
        self.interval_wall_s = interval_wall_s
        self.workers = workers or max(1, (os.cpu_count() or 2) - 1)
        self.batch_size = batch_size
        self.analyze = analyze
        self.on_duration = on_duration
        self.nice = nice
        self.rounds = 0
        self.last_round_s = 0.0
        self._pool: ProcessPoolExecutor | None = None

    async def start(self) -> None:
        """Start the worker processes (and import the analysis in each) before polling."""
        ctx = multiprocessing.get_context("spawn")
        self._pool = ProcessPoolExecutor(self.workers, mp_context=ctx,
                                         initializer=_init_worker, initargs=(self.nice,))
        loop = asyncio.get_running_loop()
        await asyncio.gather(*(loop.run_in_executor(self._pool, _warm, self.analyze)
                               for _ in range(self.workers)))

    async def stop(self) -> None:
        """Cancel queued batches, let running ones finish (at most one batch per worker, well
        under a second at the default batch size) and join the pool, off the event loop.
        Joining matters: after ``shutdown(wait=False)`` the pool's manager thread may close
        its wake-up pipe while CPython 3.11's exit hook writes to it, printing "OSError: [Errno
        9] Bad file descriptor" at exit (CPython gh-125451; the demo showed it in 2 of 5 runs)."""
        pool, self._pool = self._pool, None
        if pool is not None:
            await asyncio.to_thread(pool.shutdown, wait=True, cancel_futures=True)

    async def run(self) -> None:
        """Rounds forever, the first one interval after start."""
        loop = asyncio.get_running_loop()
        due = loop.time() + self.interval_wall_s
        while True:
            await asyncio.sleep(max(0.0, due - loop.time()))
            await self.run_round()
            due = max(due + self.interval_wall_s, loop.time())

    def _jobs(self, banks: Sequence[BankRef]) -> Iterator[list[LoopJob]]:
        for ref in banks:
            if ref.bank.count == 0:
                continue
            for lo in range(0, len(ref.loops), self.batch_size):
                cols = np.arange(lo, min(lo + self.batch_size, len(ref.loops)))
                _t, op, pv, q = ref.bank.series(cols)
                batch = []
                for k, c in enumerate(cols.tolist()):
                    cfg = ref.configs[c]
                    batch.append(LoopJob(ref.loops[c], op[k], pv[k], q[k], ref.bank.size,
                                         ref.ts, cfg.kp, cfg.delay_s, cfg.process,
                                         cfg.op_range))
                yield batch

    async def run_round(self) -> int:
        """Analyse every loop once; returns the number of loops analysed."""
        if self._pool is None:
            raise RuntimeError("AnalysisScheduler.start() was not awaited")
        loop = asyncio.get_running_loop()
        t0 = time.perf_counter()
        store = self.store  # a reload swaps the store: results go where their jobs came from
        sem = asyncio.Semaphore(2 * self.workers)
        done = 0

        async def one(batch: list[LoopJob]) -> None:
            nonlocal done
            try:
                assert self._pool is not None
                results = await loop.run_in_executor(self._pool, analyze_batch,
                                                     self.analyze, batch)
            finally:
                sem.release()
            now = time.time()
            for index, assessment, fill, samples, dur in results:
                store.set_result(index, assessment, t=now, window_fill=fill,
                                      samples=samples)
                if self.on_duration is not None:
                    self.on_duration(dur)
            done += len(results)

        # windows are copied batch by batch, only when a slot is free, so at most
        # 2 x workers batches of windows exist at once
        tasks = []
        for batch in self._jobs(list(self.banks)):
            await sem.acquire()
            tasks.append(asyncio.create_task(one(batch)))
        await asyncio.gather(*tasks)
        self.rounds += 1
        self.last_round_s = time.perf_counter() - t0
        log.debug("analysis round %d: %d loops in %.2f s", self.rounds, done, self.last_round_s)
        return done
