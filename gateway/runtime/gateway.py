"""The gateway process: assembles config → sources → windows → analysis → store → sinks.

``Gateway(config)`` is an async context manager: entering starts the analysis workers, binds
and starts the sinks (the state file is restored first, when ``persist``), then one polling
task per device and the analysis task; leaving stops the pollers, stops the sinks (the state
file is written last), closes the sources and the workers.

:meth:`Gateway.reload` applies a new config while running (SIGHUP): the carry-over is
:func:`gateway.runtime.reload.build_runtime`; devices that stay keep their poll schedule, and
every sink is bound to the new runtime. The reload is a transaction
(:mod:`gateway.runtime.reload`): a file that cannot be read or does not validate, a new
listen address in use or a runtime that cannot be built is refused and the running config
kept, untouched.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import AsyncIterator, Callable, Coroutine, Iterable, Sequence
from concurrent.futures import Executor
from types import TracebackType
from typing import Any

from prometheus_client import CollectorRegistry

from ..config import Config
from ..config.checks import ANALYSIS_BATCH_LOOPS
from ..config.plugins import output_plugin
from ..core.findings import FindingsBook
from ..core.sitecal import SiteBook
from ..core.store import ResultStore
from ..inputs.base import Source
from ..outputs.base import Binding, Sink
from ..outputs.prometheus import GatewayMetrics
from ..wire.results import moved_indices, moved_line
from .crewlist import CrewList
from .findings import load_findings, observe, read_configured
from .logs import clip
from .poller import Clocks, DevicePoller
from .reload import (
    ReloadRefused,
    Runtime,
    build_runtime,
    prepare_listeners,
    read_new_config,
    reload_summary,
)
from .scheduler import DEFAULT_ANALYZE, AnalysisScheduler

__all__ = ["Gateway"]

log = logging.getLogger("gateway.app")


class Gateway:
    """One running gateway for ``config``; see the module docstring.

    ``persist`` adds the state file, the verdict history and the site calibration's file
    (``stiction-gateway run`` sets it); ``outputs`` names further outputs of
    :data:`gateway.config.plugins.OUTPUTS` (e.g. ``memory``). ``executor`` replaces the
    analysis process pool (tests: one thread); ``clocks`` the pollers' clocks."""

    def __init__(self, config: Config, *, registry: CollectorRegistry | None = None,
                 analyze: str = DEFAULT_ANALYZE, serve_http: bool = True,
                 batch_size: int = ANALYSIS_BATCH_LOOPS, persist: bool = False,
                 outputs: Sequence[str] = (),
                 executor: Callable[[], Executor] | None = None,
                 clocks: Clocks | None = None) -> None:
        self.registry = registry if registry is not None else CollectorRegistry()
        self.metrics = GatewayMetrics(self.registry)
        self.clocks = clocks
        self._phase_ref: float | None = None
        self.runtime = build_runtime(config, wall=self._wall(), metrics=self.metrics,
                                     clocks=clocks)
        self.findings = observe(self.runtime.store, FindingsBook())  # + verdict history
        self.crew = CrewList(SiteBook(config.analysis), self.findings, wall=self._wall)
        self.sinks = create_sinks(sink_names(persist, outputs), self.runtime.binding(),
                                  registry=self.registry, metrics=self.metrics,
                                  serve_http=serve_http, findings=self.findings,
                                  site=self.crew.site)
        g = config.gateway
        self.scheduler = AnalysisScheduler(
            self.runtime.groups, self.runtime.store,
            interval_wall_s=g.analysis_interval_s / g.time_scale, workers=g.analysis_workers,
            batch_size=batch_size, analyze=analyze, executor=executor,
            on_duration=self.metrics.analysis_duration.observe, plant=config.plant,
            hysteresis=config.hysteresis, on_verdict=self.metrics.count_verdict, hooks=self.crew,
            time_scale=g.time_scale, site_adaptation=config.analysis.site_adaptation)
        self.reloads = 0
        self.polling = asyncio.Event()  # set once every poller has completed a tick
        self._polls = PollTasks()
        self._tasks: list[asyncio.Task[Any]] = []
        self._reload_lock = asyncio.Lock()

    def _wall(self) -> float:
        return self.clocks.wall() if self.clocks is not None else time.time()

    # ------------------------------------------------------------------ views

    @property
    def config(self) -> Config:
        return self.runtime.config

    @property
    def store(self) -> ResultStore:
        return self.runtime.store

    @property
    def pollers(self) -> list[DevicePoller]:
        return self.runtime.pollers

    @property
    def result_server(self) -> Any:
        return self.sinks["modbus_server"]

    @property
    def result_port(self) -> int:
        return int(self.result_server.port)

    @property
    def metrics_port(self) -> int | None:
        return getattr(self.sinks["prometheus"], "port", None)

    def align_polls(self, phase_ref: float) -> None:
        """Poll on the grid ``phase_ref + n * period`` (loop.time() seconds), not from
        start-up: the demo and tests set it half a step after the simulated PLC's steps,
        so that at high ``time_scale`` every simulated sample is read exactly once (devices
        added by a reload too)."""
        self._phase_ref = phase_ref
        for p in self.pollers:
            p.grid = type(p.grid)(p.period, phase_ref)

    # ------------------------------------------------------------------ life cycle

    async def __aenter__(self) -> Gateway:
        # never fails; bounded in time and off the event loop (config/reading.py)
        load_findings(self.findings, await asyncio.to_thread(read_configured, self.config))
        try:  # sinks first: the state file is restored before anything else takes time
            binding = self.runtime.binding()
            for sink in self.sinks.values():
                await sink.bind(binding)
                await sink.start()
            await self.scheduler.start()
            await self.crew.start(self.runtime.store, self.config)  # restored: the list
        except BaseException:
            await self._close()
            raise
        self._polls.start(self.runtime.pollers, {})
        self._spawn(self.scheduler.run(), "analysis")
        self._spawn(self._watch_first_ticks(), "first ticks")
        return self

    async def __aexit__(self, exc_type: type[BaseException] | None,
                        exc: BaseException | None, tb: TracebackType | None) -> None:
        await self._close()

    def _spawn(self, coro: Coroutine[Any, Any, Any], name: str) -> asyncio.Task[Any]:
        task = asyncio.create_task(coro, name=name)
        task.add_done_callback(_log_failure)
        self._tasks.append(task)
        return task

    async def _watch_first_ticks(self) -> None:
        await asyncio.gather(*(p.first_tick.wait() for p in self.pollers))
        self.polling.set()

    async def _close(self) -> None:
        for t in self._tasks:
            t.cancel()
        if self._tasks:
            _done, pending = await asyncio.wait(self._tasks, timeout=2.0)
            for t in pending:
                log.error("task %s did not stop; abandoned", t.get_name())
        self._tasks.clear()
        await self._polls.stop(self.runtime.pollers)
        for sink in self.sinks.values():  # pollers stopped: the state file has every sample
            with contextlib.suppress(Exception):
                await sink.stop()
        for source in self.runtime.sources.values():
            with contextlib.suppress(Exception):
                await source.close()
        await self.scheduler.stop()

    # ------------------------------------------------------------------ reload

    async def reload(self, source: str | os.PathLike[str] | Config) -> bool:
        """Apply a new config (a path or a parsed Config) as a transaction
        (:mod:`gateway.runtime.reload`): False, with one log line naming the file and the
        problem and ``stiction_config_reload_failures_total`` counted, if it cannot be read,
        does not validate, cannot bind a new listener or cannot be built; the running
        config then stays in force, untouched."""
        async with self._reload_lock:
            try:
                config = (source if isinstance(source, Config)
                          else await read_new_config(source))
                async with exclusive(self.sinks.values()):  # no state write meanwhile
                    await self._apply(config)
            except ReloadRefused as refused:
                self.metrics.reload_failures.labels(stage=refused.stage).inc()
                log.error("reload refused, keeping the running config: %s", refused.line)
                return False
            except Exception:  # a bug: still never the end of the daemon
                self.metrics.reload_failures.labels(stage="build").inc()
                log.exception("reload of %s failed unexpectedly", source)
                return False
            finally:  # the findings of the config now in force, reloaded or kept
                await self.crew.reload(self.runtime.store, self.config)
            self.reloads += 1
            return True

    async def _apply(self, config: Config) -> None:
        old = self.runtime
        swaps = await prepare_listeners(self.sinks, config)  # nothing changed yet
        if config.gateway.analysis_workers != old.config.gateway.analysis_workers:
            log.warning("reload: gateway.analysis_workers takes effect at the next restart")
        due = await self._polls.stop(old.pollers)
        try:
            new = build_runtime(config, old, wall=self._wall(), metrics=self.metrics,
                                phase_ref=self._phase_ref, clocks=self.clocks)
        except Exception as exc:  # e.g. a source that cannot be built: keep the running one
            for swap in swaps:
                await swap.abort()
            for p in old.pollers:
                p.resume()
            self._polls.start(old.pollers, due)
            text = clip(exc, 200)
            raise ReloadRefused("build", f"{config.source}: its runtime cannot be built: "
                                f"{type(exc).__name__}: {text}") from exc
        for swap in swaps:  # the new listeners take over (the old ones serve until then)
            try:
                await swap.commit()
            except Exception:  # bound already: should not happen
                log.exception("reload: a new listener could not take over")
        await _close_unused(old.sources.values(), new.sources.values())
        observe(new.store, self.findings)
        self.runtime = new
        await _bind_all(self.sinks, new.binding())
        self.scheduler.reconfigure(new.groups, new.store, config)
        # devices that stay keep their schedule (and their connection if their points are
        # unchanged); new devices start now
        self._polls.start(new.pollers, {n: d for n, d in due.items() if n in new.sources})
        _log_reloaded(old, new)

    # ------------------------------------------------------------------ health

    def stalled_pollers(self, now: float | None = None) -> list[str]:
        now = asyncio.get_running_loop().time() if now is None else now
        return [p.device.name for p in self.pollers if p.stalled(now)]

    def status_text(self) -> str:
        up = sum(1 for p in self.pollers if p.up)
        stale = int(self.store.stale.sum())
        return (f"polling {len(self.pollers)} devices ({up} up), {len(self.store.loops)} "
                f"loops ({stale} stale)")


def sink_names(persist: bool, outputs: Sequence[str]) -> list[str]:
    """The outputs of a gateway: with ``persist`` the verdict history and the state file
    (the history first: the state file's restored assessments extend it)."""
    return [*(["verdicts", "sitecal", "statefile"] if persist else []), "modbus_server",
            "prometheus", *outputs]


def create_sinks(names: Sequence[str], binding: Binding, **options: Any) -> dict[str, Sink]:
    """The outputs ``names`` (registered in :data:`gateway.config.plugins.OUTPUTS`)."""
    sinks: dict[str, Sink] = {}
    for name in names:
        plugin = output_plugin(name)
        if plugin is None:
            raise ValueError(f"unknown output {name!r}")
        sinks[name] = plugin.create_sink(binding, **options)
    return sinks


@contextlib.asynccontextmanager
async def exclusive(sinks: Iterable[Sink]) -> AsyncIterator[None]:
    """Hold every sink's ``exclusive`` lock (the state file's: a write's snapshot is a copy
    of the windows), so that a reload makes its new windows only when no such copy exists:
    never two copies at once (the memory check-config counts, config/checks.py)."""
    async with contextlib.AsyncExitStack() as held:
        for sink in sinks:
            lock = getattr(sink, "exclusive", None)
            if lock is not None:
                await held.enter_async_context(lock)
        yield


def _log_reloaded(old: Runtime, new: Runtime) -> None:
    """The reload's summary line, and a WARNING when loops moved in the config's order
    (register +19 numbers them by it: issue 38 item 13)."""
    log.info("reloaded %s", reload_summary(old, new))
    moved = moved_indices(old.store.loops, new.store.loops)
    if moved:
        log.warning("reload: %s", moved_line(moved))


async def _bind_all(sinks: dict[str, Sink], binding: Binding) -> None:
    """Bind every sink to a reloaded runtime; one that fails is logged, the others bound."""
    for name, sink in sinks.items():
        try:
            await sink.bind(binding)
        except Exception:  # an output that fails must not end the daemon
            log.exception("reload: output %s could not take the new config", name)


async def _close_unused(old: Iterable[Source], new: Iterable[Source]) -> None:
    """Close the old sources a reload did not keep."""
    kept = {id(s) for s in new}
    for s in old:
        if id(s) not in kept:
            with contextlib.suppress(Exception):
                await s.close()


class PollTasks:
    """One task per poller. Stopping asks rather than cancels: cancelling a task inside a
    pymodbus request can leave it waiting forever, so a task that does not stop in time
    is cancelled, then abandoned."""

    def __init__(self) -> None:
        self.tasks: dict[str, asyncio.Task[None]] = {}

    def start(self, pollers: Sequence[DevicePoller], due: dict[str, float | None]) -> None:
        """Run each poller, from its ``due`` time if given (a reload keeps schedules)."""
        for p in pollers:
            task = asyncio.create_task(p.run(due.get(p.device.name)),
                                       name=f"poll {p.device.name}")
            task.add_done_callback(_log_failure)
            self.tasks[p.device.name] = task

    async def stop(self, pollers: Sequence[DevicePoller]) -> dict[str, float | None]:
        """Stop every poller after its current tick; returns each one's next due time."""
        for p in pollers:
            p.request_stop()
        tasks = list(self.tasks.values())
        self.tasks.clear()
        if tasks:
            limit = max(p.guard_s for p in pollers) + 1.0
            _done, pending = await asyncio.wait(tasks, timeout=limit)
            for t in pending:
                t.cancel()
            if pending:  # a cancelled pymodbus request may never return: do not wait on it
                _done, pending = await asyncio.wait(pending, timeout=1.0)
            for t in pending:
                log.error("task %s did not stop; abandoned", t.get_name())
        return {p.device.name: p.next_due for p in pollers}


def _log_failure(task: asyncio.Task[Any]) -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("task %s failed", task.get_name(), exc_info=task.exception())
