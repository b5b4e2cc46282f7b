"""Scheduled analysis in worker processes, so the event loop keeps polling on time.

Every ``analysis_interval_s`` process seconds (``/ time_scale`` wall seconds) one round
analyses every loop: windows are copied out of the ring buffers in batches of
``batch_size`` loops (one pickle per batch, not per loop; :func:`gateway.core.jobs.batches`),
each batch runs :func:`gateway.core.jobs.analyze_batch` in a ``ProcessPoolExecutor`` worker
(spawned, never forked from the threaded gateway), and the results go into the
:class:`~gateway.core.store.ResultStore`. At most ``2 × workers`` batches are in flight,
which bounds the memory a round holds. A round that is still running when the next is due
makes that one wait (no pile-up). Workers run at a lower CPU priority (``nice`` +10 by
default), so on a busy box the polling event loop wins a contested core and analysis only
takes what is left, and they die with the gateway however it ends (:func:`die_with_parent`).
Each loop's verdict passes the verdict hysteresis (:mod:`gateway.core.hysteresis`: a change
is published when it holds ``verdict_hysteresis.rounds`` rounds or its confidence moved by
the margin; a judgement is held while the window warms up again) before the plant step and
the store. Each published verdict change of a loop is logged once, with its reason (not while
the loop is ``device_down``: the device's one line says why, not one line per loop).

With ``plant.enabled`` (the default) a round ends with the plant-wide step
(:mod:`gateway.core.plant`): the loops of each time base (poll interval and window length)
go to one worker together, :func:`stiction.plant.analyze_plant` finds the oscillations they
share and their source, and followers called ``stiction`` become ``propagated`` before the
round's results are published (so a round publishes each loop once, plant-aware). A loop in
no group keeps its per-loop assessment unchanged. One log line when a group appears,
changes its source or ends.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import logging
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, Protocol

from stiction import Assessment

from ..config.checks import ANALYSIS_BATCH_LOOPS
from ..config.model import Config, HysteresisSettings, PlantSettings
from ..core.hysteresis import VerdictFilter
from ..core.jobs import DEFAULT_ANALYZE, LoopJob, analyze_batch, batches, resolve
from ..core.plant import PlantTracker, analyze_plant_job, plant_jobs
from ..core.siteshare import SiteShare
from ..core.store import LoopResult, ResultStore
from ..core.windows import LoopGroup
from .logs import clip, sizes_text

__all__ = ["DEFAULT_ANALYZE", "WORKER_NICE", "AnalysisScheduler", "RoundHooks",
           "die_with_parent", "log_verdict_change"]

SINGLE_THREAD_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Set to 1 for the analysis workers unless already set (see
:meth:`AnalysisScheduler.start`)."""

log = logging.getLogger("gateway.analysis")
Held = tuple[Assessment, float, float, int, float, int, float | None]
"""A round's result of one loop until the plant step: (assessment, t, window fill, samples,
judged, hold, the PV's swing)."""
plant_log = logging.getLogger("gateway.plant")

WORKER_NICE = 10
"""Niceness added to each analysis worker: polling must keep its schedule under load."""


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _init_worker(increment: int, parent: int | None = None) -> None:
    """Worker initializer: die with the gateway, ignore SIGINT and lower this process's CPU
    priority (never fails the worker). A Ctrl-C reaches every process of the terminal's
    group; the gateway handles it and stops the pool, so the workers must not die of it
    first (each printed a KeyboardInterrupt traceback after "demo stopped")."""
    if parent is not None:
        die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if increment > 0:
        with contextlib.suppress(OSError, AttributeError):
            os.nice(increment)


def die_with_parent(parent: int) -> None:
    """End this process when process ``parent`` ends, however it ends (SIGKILL, a crash):
    Linux's parent-death signal, else a thread that watches for the parent to go. Without
    it a killed gateway left its workers (and multiprocessing's resource tracker, which
    waits for them) running under PID 1."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
            if os.getppid() != parent:  # it died before we asked
                os._exit(1)
            return
    except (OSError, AttributeError):
        pass
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True,
                     name="watch parent").start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


def _warm(path: str) -> int:
    resolve(path)
    return os.getpid()


class RoundHooks(Protocol):
    """What a round calls besides the analysis (:class:`gateway.runtime.crewlist.CrewList`):
    each loop's assessment under the site's calibration, before the hysteresis (name,
    assessment, wall time); the list worst first after the round."""

    def calibrate(self, loop: str, a: Assessment, t: float) -> Assessment: ...

    def after_round(self, store: ResultStore) -> None: ...


JOINED = ("after ``shutdown(wait=False)`` the pool's manager thread may close its wake-up "
          "pipe while CPython 3.11's exit hook writes to it, printing 'OSError: [Errno 9] Bad "
          "file descriptor' at exit (CPython gh-125451; the demo showed it in 2 of 5 runs); a "
          "running batch is at most one per worker, well under a second at the default size")
"""Why :meth:`AnalysisScheduler.stop` joins the pool."""


class AnalysisScheduler:
    """Runs analysis rounds over ``groups`` and writes the results into ``store``.

    ``executor`` (tests) replaces the process pool by another executor, e.g. one thread."""

    def __init__(self, groups: Sequence[LoopGroup], store: ResultStore, *,
                 interval_wall_s: float, workers: int = 0, batch_size: int = ANALYSIS_BATCH_LOOPS,
                 analyze: str = DEFAULT_ANALYZE,
                 on_duration: Callable[[float], None] | None = None,
                 nice: int = WORKER_NICE,
                 executor: Callable[[], Executor] | None = None,
                 plant: PlantSettings | None = None,
                 hysteresis: HysteresisSettings | None = None,
                 on_verdict: Callable[[str], None] | None = None,
                 time_scale: float = 1.0, hooks: RoundHooks | None = None,
                 site_adaptation: bool = True) -> None:
        self.store = store
        self.time_scale = time_scale
        self.groups = list(groups)  # (sets the windows' lengths: the longest hold)
        self.interval_wall_s = interval_wall_s
        self.workers = workers or max(1, (os.cpu_count() or 2) - 1)
        self.batch_size = batch_size
        self.analyze = analyze
        self.on_duration = on_duration
        self.nice = nice
        self.tracker = PlantTracker()
        self.plant = plant if plant is not None else PlantSettings()
        # each loop's verdict passes it before it is published (core/hysteresis.py)
        self.verdicts = VerdictFilter(hysteresis, on_count=on_verdict)
        self.rounds, self.last_round_s, self.last_plant_s = 0, 0.0, 0.0
        self._executor = executor
        self._pool: Executor | None = None
        self.hooks = hooks  # the site's calibration and the list worst first (crewlist)
        self.site = SiteShare(site_adaptation)  # the loops' share of sticky valves

    @property
    def groups(self) -> list[LoopGroup]:
        """The windows analysed (a reload sets them; each loop's window length, in wall
        seconds, bounds how long its judgement is held through warming up)."""
        return self._groups

    @groups.setter
    def groups(self, groups: list[LoopGroup]) -> None:
        self._groups = groups
        self._windows_s = {cfg.name: g.bank.size * g.ts / self.time_scale
                           for g in groups for cfg in g.configs}

    @property
    def plant(self) -> PlantSettings:
        """The plant step's settings (a reload sets them; the tracker holds its view)."""
        return self._plant

    @plant.setter
    def plant(self, settings: PlantSettings) -> None:
        self._plant = settings
        self.tracker.hold.rounds = settings.hold_rounds

    def reconfigure(self, groups: Sequence[LoopGroup], store: ResultStore, config: Config
                    ) -> None:
        """After a reload: the new runtime's windows and store, and the new settings (each
        loop's verdict hysteresis state stays, by name)."""
        g = config.gateway
        self.store, self.time_scale = store, g.time_scale
        self.groups = list(groups)
        self.interval_wall_s = g.analysis_interval_s / g.time_scale
        self.plant = config.plant
        self.site.enabled = config.analysis.site_adaptation
        self.verdicts.settings = config.hysteresis
        # a loop whose result the reload did not carry (its window, or its config, changed)
        # starts fresh, its hold included (issue 35 item 5)
        self.verdicts.keep(name for name, res in zip(store.loops, store.results, strict=True)
                           if res is not None)

    async def start(self) -> None:
        """Start the worker processes (and import the analysis in each) before polling."""
        if self._executor is not None:
            self._pool = self._executor()
            return
        ctx = multiprocessing.get_context("spawn")
        # one worker per core, each on one BLAS thread: a BLAS that spreads one window's
        # products over threads only contends with the other workers (the spawned workers
        # take this environment; a value the operator set wins)
        for var in SINGLE_THREAD_ENV:
            os.environ.setdefault(var, "1")
        self._pool = ProcessPoolExecutor(self.workers, mp_context=ctx,
                                         initializer=_init_worker,
                                         initargs=(self.nice, os.getpid()))
        loop = asyncio.get_running_loop()
        await asyncio.gather(*(loop.run_in_executor(self._pool, _warm, self.analyze)
                               for _ in range(self.workers)))

    async def stop(self) -> None:
        """Cancel queued batches, let running ones finish and join the pool, off the event
        loop (why joining matters: :data:`JOINED`)."""
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

    async def run_round(self, now: Callable[[], float] = time.time) -> int:
        """Analyse every loop once; returns the number of loops analysed. ``now`` stamps
        the results (wall time)."""
        if self._pool is None:
            raise RuntimeError("AnalysisScheduler.start() was not awaited")
        loop = asyncio.get_running_loop()
        t0 = time.perf_counter()
        store = self.store  # a reload swaps the store: results go where their jobs came from
        sem = asyncio.Semaphore(2 * self.workers)
        done = 0
        held: dict[int, Held] | None = {} if self.plant.enabled else None
        self.site.estimate(store)  # from the latest results (restored ones after a restart)

        async def one(batch: list[LoopJob]) -> None:
            nonlocal done
            try:
                assert self._pool is not None
                results = await loop.run_in_executor(self._pool, analyze_batch,
                                                     self.analyze, batch)
            finally:
                sem.release()
            t = now()
            for index, raw, fill, samples, dur, swing in results:
                shown, name = store.results[index], store.loops[index]
                at_site = self.site.apply(raw)
                analysed = at_site if self.hooks is None else \
                    self.hooks.calibrate(name, at_site, t)
                assessment = self.verdicts.publish(
                    name, analysed, t, shown=None if shown is None else shown.assessment,
                    shown_at=None if shown is None else shown.judged_at,
                    max_hold_s=self._windows_s.get(name))
                judged, hold = self.verdicts.published(name, t)
                if held is not None:  # published after the plant step
                    held[index] = (assessment, t, fill, samples, judged, hold, swing)
                else:
                    publish(store, index, assessment, t=t, fill=fill, samples=samples,
                            judged=judged, hold=hold, pv_swing=swing)
                if self.on_duration is not None:
                    self.on_duration(dur)
            done += len(results)

        self.verdicts.keep(store.loops)
        # windows are copied batch by batch, only when a slot is free, so at most
        # 2 x workers batches of windows exist at once
        tasks = []
        groups = list(self.groups)
        for batch in batches(groups, self.batch_size):
            await sem.acquire()
            tasks.append(asyncio.create_task(one(batch)))
        await asyncio.gather(*tasks)
        if held is not None:
            applied = await self._plant_step(store, groups, held)
            for index, (assessment, t, fill, samples, judged, hold, swing) in held.items():
                publish(store, index, applied.get(index, assessment), t=t, fill=fill,
                        samples=samples, judged=judged, hold=hold, pv_swing=swing)
        elif self.tracker.groups:  # turned off by a reload: the groups end
            self._set_plant(store, [])
        if self.hooks is not None:
            self.hooks.after_round(store)
        self.rounds += 1
        self.last_round_s = time.perf_counter() - t0
        log.debug("analysis round %d: %d loops in %.2f s", self.rounds, done, self.last_round_s)
        return done


    async def _plant_step(self, store: ResultStore, groups: Sequence[LoopGroup],
                          held: dict[int, Held]) -> dict[int, Assessment]:
        """The plant analysis of this round's loops, one worker job per poll interval; the
        store's plant view set; returns the plant-aware assessments of the loops it
        changed. A failure is logged and changes nothing (the per-loop results stand)."""
        t0 = time.perf_counter()
        loop = asyncio.get_running_loop()
        try:
            jobs = plant_jobs(groups, {i: a for i, (a, *_rest) in held.items()},
                              max_samples=self.plant.max_samples,
                              previous=self.tracker.in_force)
            outs = await asyncio.gather(*(loop.run_in_executor(self._pool, analyze_plant_job, job)
                                          for job in jobs))
        except Exception:  # a bug in the plant view must not stop the per-loop results
            log.exception("plant analysis failed; per-loop results published as they are")
            return {}
        applied, view, events = self.tracker.round(jobs, outs)
        for line in events:
            plant_log.info("%s", line)
        store.set_plant(view)
        self.last_plant_s = time.perf_counter() - t0
        return applied

    def _set_plant(self, store: ResultStore, found: list[tuple[Any, Sequence[str]]]) -> None:
        view, events = self.tracker.update(found)
        for line in events:
            plant_log.info("%s", line)
        store.set_plant(view)


def publish(store: ResultStore, index: int, assessment: Assessment, *, t: float,
            fill: float, samples: int, judged: float | None = None, hold: int = 0,
            pv_swing: float | None = None) -> None:
    """One loop's result into the store, its verdict change logged (not while its device is
    down: the device's line says why)."""
    before = store.results[index]
    store.set_result(index, assessment, t=t, window_fill=fill, samples=samples,
                     judged=judged, hold=hold, pv_swing=pv_swing)
    if not (store.stale[index] and store.down[index]):
        log_verdict_change(store.loops[index], before, assessment)


def log_verdict_change(loop: str, before: LoopResult | None, after: Assessment) -> None:
    """One INFO line when a loop's verdict changes (the first assessment too), with the
    reason: the journal tells each loop's story; a WARNING when the valve's position given
    stops being used (:attr:`stiction.Assessment.position_use`)."""
    used = before.assessment.position_use if before is not None else None
    if after.position_use not in (None, "used") and after.position_use != used:
        log.warning("loop %s: its valve position is not used (%s): OP and PV decide; see "
                    "its reason", loop, after.position_use.replace("_", " "))
    was = str(before.assessment.verdict) if before is not None else "none"
    if was == str(after.verdict):
        return
    sized = sizes_text(after)
    log.info("loop %s: verdict %s (was %s)%s: %s", loop, after.verdict, was,
             f", {sized} (as its registers)" if sized else "", clip(after.reason))
