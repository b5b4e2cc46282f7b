"""The gateway process: wires config → inputs → windows → analysis → store → outputs.

``Gateway(config)`` is an async context manager: entering restores the state file (when
``persist``), starts the analysis workers, the Modbus result server, the metrics HTTP
server, one polling task per device, the analysis task and the persistence task; leaving
stops the pollers, writes the state file, and closes everything.

:meth:`Gateway.reload` applies a new config while running (SIGHUP): devices whose
connection and points are unchanged keep their connection and poll schedule, loops whose
window signature is unchanged keep their windows (and their latest assessment if nothing
else changed), added loops start fresh, removed loops vanish from the registers and the
metrics. A config that does not validate is refused and the running one kept.

:func:`run` is the ``stiction-gateway run`` entry: it runs until SIGTERM or SIGINT,
reloads on SIGHUP and speaks the systemd notify protocol (READY, STATUS, WATCHDOG only
while every poller makes progress, RELOADING, STOPPING). See docs/reliability.md.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any
from wsgiref.simple_server import WSGIServer

import numpy as np
from prometheus_client import CollectorRegistry

from ..config import Config, DeviceConfig, LoopConfig, load_config
from ..core.store import ResultStore
from ..core.ticks import Backoff
from ..core.windows import WindowBank
from ..errors import ConfigError
from ..inputs import DeviceInput, PointSpec, protocol_plugin
from ..outputs.prometheus.collector import GatewayMetrics, serve_metrics
from ..outputs.statefile.format import (
    BankState,
    load_columns,
    loop_signature,
    restore_state,
    result_signature,
    snapshot,
    write_state,
)
from ..wire.registers import ResultServer
from .poller import BACKOFF_BASE_S, BankSlot, DevicePoller, ProcessClock
from .scheduler import DEFAULT_ANALYZE, AnalysisScheduler, BankRef
from .sdnotify import Notifier, watchdog_interval

__all__ = ["Gateway", "run", "serve"]

log = logging.getLogger("gateway.app")


def _points(loops: tuple[LoopConfig, ...]) -> list[PointSpec]:
    points: list[PointSpec] = []
    for lp in loops:
        points.append(PointSpec(lp.name, "op", lp.op.address, lp.op.scale, lp.op.offset,
                                lp.op.range))
        points.append(PointSpec(lp.name, "pv", lp.pv.address, lp.pv.scale, lp.pv.offset,
                                lp.pv.range))
    return points


@dataclasses.dataclass
class _Runtime:
    """Everything built from one config: the store, the adapters, windows and pollers."""

    config: Config
    clock: ProcessClock
    store: ResultStore
    pollers: list[DevicePoller]
    adapter_keys: dict[str, tuple[DeviceConfig, list[PointSpec]]]
    bank_refs: list[BankRef]
    bank_states: list[BankState]

    @property
    def adapters(self) -> dict[str, DeviceInput]:
        return {p.device.name: p.adapter for p in self.pollers}


class Gateway:
    """One running gateway for ``config``; see the module docstring.

    ``persist`` enables the state file (``gateway.state_file``): restored on entry, written
    every ``gateway.persist_interval_s`` and on exit. ``stiction-gateway run`` enables it;
    tests and embedders choose."""

    def __init__(self, config: Config, *, registry: CollectorRegistry | None = None,
                 analyze: str = DEFAULT_ANALYZE, serve_http: bool = True,
                 batch_size: int = 64, persist: bool = False) -> None:
        self.registry = registry if registry is not None else CollectorRegistry()
        self._phase_ref: float | None = None
        self.metrics = GatewayMetrics(self.registry)
        self.runtime = self._build(config, None)
        self.metrics.set_store(self.runtime.store)
        for dev in config.devices:
            self.metrics.add_device(dev.name)
        self.result_server = ResultServer(config.modbus_server, config.loops,
                                          self.runtime.store)
        g = config.gateway
        self.scheduler = AnalysisScheduler(
            self.runtime.bank_refs, self.runtime.store,
            interval_wall_s=g.analysis_interval_s / g.time_scale,
            workers=g.analysis_workers, batch_size=batch_size, analyze=analyze,
            on_duration=self.metrics.analysis_duration.observe)
        self.serve_http = serve_http
        self.persist = persist
        self.reloads = 0
        self.saves = 0
        self.last_save_s = 0.0  # wall time the last state write took
        self.polling = asyncio.Event()  # set once every poller has completed a tick
        self._http: tuple[WSGIServer, threading.Thread] | None = None
        self._poll_tasks: dict[str, asyncio.Task[None]] = {}
        self._tasks: list[asyncio.Task[Any]] = []
        self._reload_lock = asyncio.Lock()
        self._save_lock = asyncio.Lock()

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
    def clock(self) -> ProcessClock:
        return self.runtime.clock

    @property
    def metrics_port(self) -> int | None:
        return self._http[0].server_port if self._http else None

    @property
    def result_port(self) -> int:
        return self.result_server.port

    def loop_config(self, name: str) -> LoopConfig:
        return self.config.loops[self.store.index[name]]

    def align_polls(self, phase_ref: float) -> None:
        """Poll on the grid ``phase_ref + n * period`` (loop.time() seconds) instead of
        from start-up. The demo and tests set it half a step after the simulated PLC's
        steps, so that at high ``time_scale`` every simulated sample is read exactly once
        (timer jitter of a millisecond is a large part of a 25 ms step). Devices added by
        a reload follow the same grid."""
        self._phase_ref = phase_ref
        for p in self.pollers:
            p.phase_ref = phase_ref

    # ------------------------------------------------------------------ building

    def _build(self, config: Config, old: _Runtime | None) -> _Runtime:
        """Build a runtime for ``config``. With ``old`` (a reload, its pollers stopped):
        reuse the adapters of unchanged devices, copy the windows of loops whose window
        signature is unchanged and the results of loops whose config is unchanged."""
        g = config.gateway
        clock = (old.clock if old is not None and old.clock.time_scale == g.time_scale
                 else ProcessClock(g.time_scale))
        store = ResultStore([lp.name for lp in config.loops])
        index = store.index
        old_cols: dict[str, tuple[WindowBank, int, str, str]] = {}
        if old is not None:
            for ref in old.bank_states:
                for c, lc in enumerate(ref.configs):
                    old_cols[lc.name] = (ref.bank, c, loop_signature(old.config, lc),
                                         result_signature(old.config, lc))
        pollers: list[DevicePoller] = []
        keys: dict[str, tuple[DeviceConfig, list[PointSpec]]] = {}
        bank_refs: list[BankRef] = []
        bank_states: list[BankState] = []
        for dev in config.devices:
            loops = config.loops_of(dev.name)
            points = _points(loops)
            keys[dev.name] = (dev, points)
            adapter: DeviceInput | None = None
            old_poller = None
            if old is not None and old.adapter_keys.get(dev.name) == (dev, points):
                old_poller = next(p for p in old.pollers if p.device.name == dev.name)
                adapter = old_poller.adapter
            if adapter is None:
                plugin = protocol_plugin(dev.protocol)
                assert plugin is not None  # validated at load
                adapter = plugin.create_input(dev, points, time_scale=g.time_scale)
            by_size: dict[int, list[int]] = {}
            for k, lp in enumerate(loops):
                by_size.setdefault(config.window_samples(lp), []).append(k)
            slots = []
            for size, members in by_size.items():
                bank = WindowBank([loops[k].name for k in members], size)
                ks = np.array(members, dtype=np.intp)
                rows = np.array([index[loops[k].name] for k in members], dtype=np.intp)
                configs = [loops[k] for k in members]
                slots.append(BankSlot(bank, 2 * ks, 2 * ks + 1, rows))
                bank_refs.append(BankRef(bank, rows.tolist(), configs, dev.poll_interval_s))
                bank_states.append(BankState(bank, configs, dev.poll_interval_s))
                if old is not None:
                    self._carry_over(config, bank, configs, old_cols)
            poller = DevicePoller(dev, adapter, slots, store=store, metrics=self.metrics,
                                  clock=clock, n_points=len(points), points=points,
                                  backoff=Backoff(min(BACKOFF_BASE_S, g.reconnect_max_s),
                                                  2.0, g.reconnect_max_s))
            poller.phase_ref = self._phase_ref
            if old_poller is not None:
                poller.take_over(old_poller)
            pollers.append(poller)
        return _Runtime(config, clock, store, pollers, keys, bank_refs, bank_states)

    @staticmethod
    def _carry_over(config: Config, bank: WindowBank, configs: list[LoopConfig],
                    old_cols: dict[str, tuple[WindowBank, int, str, str]]) -> None:
        """Copy into a fresh ``bank`` the old windows of loops whose signature held."""
        columns = {}
        t_best: Any = np.empty(0)
        for col, lc in enumerate(configs):
            hit = old_cols.get(lc.name)
            if hit is None or hit[2] != loop_signature(config, lc):
                continue
            old_bank, c, _sig, _rsig = hit
            t, op, pv, q = old_bank.series([c])
            columns[col] = (op[0], pv[0], q[0])
            if len(t) > len(t_best):
                t_best = t
        if columns:
            load_columns(bank, t_best, columns)

    @staticmethod
    def _carry_results(old: _Runtime, new: _Runtime) -> None:
        for name, i in new.store.index.items():
            j = old.store.index.get(name)
            if j is None:
                continue
            lc_new, lc_old = new.config.loops[i], old.config.loops[j]
            if result_signature(new.config, lc_new) == result_signature(old.config, lc_old):
                res = old.store.results[j]
                if res is not None:
                    new.store.restore_result(i, res)
                new.store.latest_op[i] = old.store.latest_op[j]
                new.store.latest_pv[i] = old.store.latest_pv[j]
                new.store.stale[i] = old.store.stale[j]

    # ------------------------------------------------------------------ lifecycle

    async def __aenter__(self) -> Gateway:
        if self.persist:
            self._restore()
        await self.scheduler.start()
        try:
            await self.result_server.start()
            if self.serve_http:
                host, port = self.config.metrics.listen
                self._http = serve_metrics(self.registry, host, port)
        except BaseException:
            await self._close()
            raise
        self._start_pollers(self.runtime, {})
        self._spawn(self.scheduler.run(), "analysis")
        self._spawn(self._watch_first_ticks(), "first ticks")
        if self.persist:
            self._spawn(self._persist_loop(), "persist")
        return self

    def _spawn(self, coro: Any, name: str) -> asyncio.Task[Any]:
        task = asyncio.create_task(coro, name=name)
        task.add_done_callback(self._task_done)
        self._tasks.append(task)
        return task

    def _start_pollers(self, rt: _Runtime, due: dict[str, float | None]) -> None:
        for p in rt.pollers:
            task = asyncio.create_task(p.run(due.get(p.device.name)),
                                       name=f"poll {p.device.name}")
            task.add_done_callback(self._task_done)
            self._poll_tasks[p.device.name] = task

    async def _stop_pollers(self, rt: _Runtime) -> dict[str, float | None]:
        """Stop every poller after its current tick; returns each one's next due time."""
        for p in rt.pollers:
            p.request_stop()
        tasks = list(self._poll_tasks.values())
        self._poll_tasks.clear()
        if tasks:
            limit = max(p.guard_s for p in rt.pollers) + 1.0
            _done, pending = await asyncio.wait(tasks, timeout=limit)
            for t in pending:
                t.cancel()
            if pending:  # a cancelled pymodbus request may never return: do not wait on it
                _done, pending = await asyncio.wait(pending, timeout=1.0)
            for t in pending:
                log.error("task %s did not stop; abandoned", t.get_name())
        return {p.device.name: p.next_due for p in rt.pollers}

    async def _watch_first_ticks(self) -> None:
        await asyncio.gather(*(p.first_tick.wait() for p in self.pollers))
        self.polling.set()

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        if not task.cancelled() and task.exception() is not None:
            log.error("task %s failed", task.get_name(), exc_info=task.exception())

    async def __aexit__(self, exc_type: type[BaseException] | None,
                        exc: BaseException | None, tb: TracebackType | None) -> None:
        await self._close()

    async def _close(self) -> None:
        for t in self._tasks:
            t.cancel()
        if self._tasks:
            _done, pending = await asyncio.wait(self._tasks, timeout=2.0)
            for t in pending:
                log.error("task %s did not stop; abandoned", t.get_name())
        self._tasks.clear()
        await self._stop_pollers(self.runtime)
        if self.persist:
            try:
                await self.save_state()
            except Exception:
                log.exception("state file: final write failed")
        for adapter in self.runtime.adapters.values():
            with contextlib.suppress(Exception):
                await adapter.close()
        if self._http is not None:
            self._stop_http()
        with contextlib.suppress(Exception):
            await self.result_server.stop()
        await self.scheduler.stop()

    def _stop_http(self) -> None:
        assert self._http is not None
        server, thread = self._http
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
        self._http = None

    # ------------------------------------------------------------------ state file

    def _restore(self) -> None:
        rt = self.runtime
        restore_state(rt.config.gateway.state_file, rt.config, rt.bank_states, rt.store,
                      wall=time.time(), time_scale=rt.clock.time_scale)

    async def save_state(self) -> int:
        """Write the state file now (atomically); returns its size in bytes."""
        async with self._save_lock:
            rt = self.runtime
            wall = time.time()
            header, arrays = snapshot(rt.config, rt.bank_states, rt.store, wall=wall,
                                      proc=rt.clock.now(wall))
            t0 = time.perf_counter()
            size = await asyncio.to_thread(write_state, rt.config.gateway.state_file,
                                           header, arrays)
            self.last_save_s = time.perf_counter() - t0
            self.saves += 1
            log.debug("state file %s: %d bytes in %.3f s", rt.config.gateway.state_file,
                      size, self.last_save_s)
            return size

    async def _persist_loop(self) -> None:
        failing = False
        while True:
            await asyncio.sleep(self.config.gateway.persist_interval_s)
            try:
                await self.save_state()
            except Exception as exc:  # a full disk must not stop the gateway
                if not failing:
                    log.error("state file %s: write failed: %s (retrying every %g s)",
                              self.config.gateway.state_file, exc,
                              self.config.gateway.persist_interval_s)
                failing = True
            else:
                if failing:
                    log.warning("state file %s: writing again", self.config.gateway.state_file)
                failing = False

    # ------------------------------------------------------------------ reload

    async def reload(self, source: str | os.PathLike[str] | Config) -> bool:
        """Apply a new config (a path or a parsed Config). False, with the reasons logged,
        if it does not validate: the running config stays in force."""
        async with self._reload_lock:
            if isinstance(source, Config):
                new_config = source
            else:
                try:  # parsed in a thread: a big YAML file takes a while, polls go on
                    new_config = await asyncio.to_thread(load_config, source)
                except ConfigError as exc:
                    log.error("reload refused, keeping the running config: %d problem(s) "
                              "in %s:\n  %s", len(exc.problems), source,
                              "\n  ".join(exc.problems))
                    return False
            if not await self._apply(new_config):
                return False
            self.reloads += 1
            return True

    async def _apply(self, config: Config) -> bool:
        old = self.runtime
        old_g, g = old.config.gateway, config.gateway
        if g.analysis_workers != old_g.analysis_workers:
            log.warning("reload: gateway.analysis_workers takes effect at the next restart")
        if g.state_file != old_g.state_file:
            log.warning("reload: state is written to %s from now on (not restored)",
                        g.state_file)
        due = await self._stop_pollers(old)
        try:
            new = self._build(config, old)
            self._carry_results(old, new)
        except Exception:  # e.g. an adapter that cannot be built: keep the running config
            log.exception("reload failed, keeping the running config")
            for p in old.pollers:
                p.resume()
            self._start_pollers(old, due)
            return False
        reused = {id(p.adapter) for p in new.pollers}
        for p in old.pollers:
            if id(p.adapter) not in reused:
                with contextlib.suppress(Exception):
                    await p.adapter.close()
        self.runtime = new
        old_devices = {d.name for d in old.config.devices}
        new_devices = {d.name for d in config.devices}
        for name in sorted(old_devices - new_devices):
            self.metrics.remove_device(name)
        for name in sorted(new_devices - old_devices):
            self.metrics.add_device(name)
        self.metrics.set_store(new.store)
        self.scheduler.banks = list(new.bank_refs)
        self.scheduler.store = new.store
        self.scheduler.interval_wall_s = g.analysis_interval_s / g.time_scale
        if config.modbus_server != old.config.modbus_server \
                or not self.result_server.serves(config.loops):
            # new settings, or a result unit id the running server has no device for
            await self.result_server.stop()
            self.result_server = ResultServer(config.modbus_server, config.loops, new.store)
            await self.result_server.start()
        else:
            self.result_server.rebind(config.loops, new.store)
        if self.serve_http and config.metrics != old.config.metrics:
            if self._http is not None:
                self._stop_http()
            host, port = config.metrics.listen
            self._http = serve_metrics(self.registry, host, port)
        # devices that stay keep their schedule (and their connection if their points
        # are unchanged); new devices start now
        self._start_pollers(new, {n: d for n, d in due.items() if n in new_devices})
        old_loops = {lp.name for lp in old.config.loops}
        new_loops = {lp.name for lp in config.loops}
        kept = sum(1 for ref in new.bank_states for lc in ref.configs
                   if lc.name in old_loops and ref.bank.count > 0)
        log.info("reloaded %s: %d devices, %d loops (%d added, %d removed, %d windows kept)",
                 config.source, len(config.devices), len(config.loops),
                 len(new_loops - old_loops), len(old_loops - new_loops), kept)
        return True

    # ------------------------------------------------------------------ health

    def stalled_pollers(self) -> list[str]:
        loop = asyncio.get_running_loop()
        now = loop.time()
        return [p.device.name for p in self.pollers if p.stalled(now)]

    def status_text(self) -> str:
        up = sum(1 for p in self.pollers if p.up)
        stale = int(self.store.stale.sum())
        return (f"polling {len(self.pollers)} devices ({up} up), {len(self.store.loops)} "
                f"loops ({stale} stale)")


# ---------------------------------------------------------------------- the daemon


async def _watchdog(gw: Gateway, notifier: Notifier, interval: float) -> None:
    """WATCHDOG=1 every ``interval`` while every poller makes progress; silence otherwise,
    so systemd restarts a gateway whose polling hangs."""
    stalled_before: list[str] = []
    while True:
        await asyncio.sleep(interval)
        stalled = gw.stalled_pollers()
        if not stalled:
            notifier.watchdog()
            if stalled_before:
                log.warning("polling progresses again; watchdog pings resumed")
        elif stalled != stalled_before:
            log.error("polling stalled for %s; withholding the watchdog ping",
                      ", ".join(stalled))
        stalled_before = stalled


async def serve(config: Config, stop: asyncio.Event, *, reload: asyncio.Event | None = None,
                config_path: str | os.PathLike[str] | None = None,
                notifier: Notifier | None = None,
                on_started: Callable[[Gateway], None] | None = None, **kwargs: Any) -> None:
    """Run a gateway until ``stop`` is set; each time ``reload`` is set, reload the config
    from ``config_path``."""
    notifier = notifier or Notifier(address="")
    async with Gateway(config, **kwargs) as gw:
        log.info("gateway running: %d devices, %d loops; metrics on %s:%s, "
                 "Modbus results on %s:%s (unit ids %s)", len(config.devices),
                 len(config.loops), config.metrics.listen[0], gw.metrics_port,
                 config.modbus_server.listen[0], gw.result_port,
                 ", ".join(map(str, sorted(gw.result_server.unit_ids_of(config.loops)))))
        if on_started is not None:
            on_started(gw)
        waiter = asyncio.create_task(stop.wait())
        polling = asyncio.create_task(gw.polling.wait())
        await asyncio.wait({waiter, polling}, return_when=asyncio.FIRST_COMPLETED)
        polling.cancel()
        if not stop.is_set():
            notifier.ready(gw.status_text())
        wd_task = None
        interval = watchdog_interval()
        if interval is not None and notifier.enabled:
            wd_task = asyncio.create_task(_watchdog(gw, notifier, interval), name="watchdog")
        try:
            while not stop.is_set():
                reload_wait = asyncio.create_task(reload.wait()) if reload else None
                pending = {waiter} | ({reload_wait} if reload_wait else set())
                await asyncio.wait(pending, timeout=30.0, return_when=asyncio.FIRST_COMPLETED)
                if reload_wait is not None and not reload_wait.done():
                    reload_wait.cancel()
                if reload is not None and reload.is_set() and not stop.is_set():
                    reload.clear()
                    notifier.reloading()
                    path = config_path if config_path is not None else config.source
                    await gw.reload(path)
                    notifier.ready(gw.status_text())
                elif not stop.is_set():
                    notifier.status(gw.status_text())
        finally:
            notifier.stopping()
            log.info("gateway stopping")
            if wd_task is not None:
                wd_task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await wd_task
            waiter.cancel()
    log.info("gateway stopped")


def install_stop_signals(stop: asyncio.Event) -> None:
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)


def run(config: Config, config_path: str | os.PathLike[str] | None = None) -> int:
    """``stiction-gateway run``: serve until SIGTERM/SIGINT, reload on SIGHUP, keep the
    state file; returns the exit status."""

    async def main() -> None:
        stop = asyncio.Event()
        reload = asyncio.Event()
        install_stop_signals(stop)
        asyncio.get_running_loop().add_signal_handler(signal.SIGHUP, reload.set)
        notifier = Notifier()
        try:
            await serve(config, stop, reload=reload, notifier=notifier,
                        config_path=config_path or Path(config.source), persist=True)
        finally:
            notifier.close()

    asyncio.run(main())
    return 0
