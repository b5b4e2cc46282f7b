"""The gateway process: wires config → inputs → windows → analysis → store → outputs.

``Gateway(config)`` is an async context manager: entering starts the analysis workers, the
Modbus result server, the metrics HTTP server, one polling task per device and the
analysis task; leaving cancels and awaits the tasks and closes everything. :func:`run` is the
``stiction-gateway run`` entry: it runs until SIGTERM or SIGINT, then shuts down cleanly.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import threading
from types import TracebackType
from typing import Any
from wsgiref.simple_server import WSGIServer

import numpy as np
from prometheus_client import CollectorRegistry

from .analysis import DEFAULT_ANALYZE, AnalysisScheduler, BankRef
from .config import Config, LoopConfig
from .inputs import PointSpec, protocol_plugin
from .metrics import GatewayMetrics, serve_metrics
from .poller import BankSlot, DevicePoller, ProcessClock
from .result_server import ResultServer
from .store import ResultStore
from .windows import WindowBank

__all__ = ["Gateway", "run"]

log = logging.getLogger(__name__)


class Gateway:
    """One running gateway for ``config``; see the module docstring."""

    def __init__(self, config: Config, *, registry: CollectorRegistry | None = None,
                 analyze: str = DEFAULT_ANALYZE, serve_http: bool = True,
                 batch_size: int = 64) -> None:
        self.config = config
        self.registry = registry if registry is not None else CollectorRegistry()
        self.store = ResultStore([lp.name for lp in config.loops])
        self.metrics = GatewayMetrics(self.registry, self.store)
        self.clock = ProcessClock(config.gateway.time_scale)
        self.result_server = ResultServer(config.modbus_server, config.loops, self.store)
        self.pollers: list[DevicePoller] = []
        bank_refs: list[BankRef] = []
        index = self.store.index
        for dev in config.devices:
            loops = config.loops_of(dev.name)
            points: list[PointSpec] = []
            for lp in loops:
                points.append(PointSpec(lp.name, "op", lp.op.address, lp.op.scale, lp.op.offset))
                points.append(PointSpec(lp.name, "pv", lp.pv.address, lp.pv.scale, lp.pv.offset))
            plugin = protocol_plugin(dev.protocol)
            assert plugin is not None  # validated at load
            adapter = plugin.create_input(dev, points, time_scale=config.gateway.time_scale)
            by_size: dict[int, list[int]] = {}
            for k, lp in enumerate(loops):
                by_size.setdefault(config.window_samples(lp), []).append(k)
            slots = []
            for size, members in by_size.items():
                bank = WindowBank([loops[k].name for k in members], size)
                ks = np.array(members, dtype=np.intp)
                store_rows = np.array([index[loops[k].name] for k in members], dtype=np.intp)
                slots.append(BankSlot(bank, 2 * ks, 2 * ks + 1, store_rows))
                bank_refs.append(BankRef(bank, store_rows.tolist(),
                                         [loops[k] for k in members], dev.poll_interval_s))
            self.metrics.add_device(dev.name)
            self.pollers.append(DevicePoller(dev, adapter, slots, store=self.store,
                                             metrics=self.metrics, clock=self.clock,
                                             n_points=len(points)))
        g = config.gateway
        self.scheduler = AnalysisScheduler(
            bank_refs, self.store, interval_wall_s=g.analysis_interval_s / g.time_scale,
            workers=g.analysis_workers, batch_size=batch_size, analyze=analyze,
            on_duration=self.metrics.analysis_duration.observe)
        self.serve_http = serve_http
        self._http: tuple[WSGIServer, threading.Thread] | None = None
        self._tasks: list[asyncio.Task[Any]] = []

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
        (timer jitter of a millisecond is a large part of a 25 ms step)."""
        for p in self.pollers:
            p.phase_ref = phase_ref

    async def __aenter__(self) -> Gateway:
        await self.scheduler.start()
        try:
            await self.result_server.start()
            if self.serve_http:
                host, port = self.config.metrics.listen
                self._http = serve_metrics(self.registry, host, port)
        except BaseException:
            await self._close()
            raise
        for p in self.pollers:
            self._tasks.append(asyncio.create_task(p.run(), name=f"poll {p.device.name}"))
        self._tasks.append(asyncio.create_task(self.scheduler.run(), name="analysis"))
        for t in self._tasks:
            t.add_done_callback(self._task_done)
        return self

    def _task_done(self, task: asyncio.Task[Any]) -> None:
        if not task.cancelled() and task.exception() is not None:
            log.error("task %s failed", task.get_name(), exc_info=task.exception())

    async def __aexit__(self, exc_type: type[BaseException] | None,
                        exc: BaseException | None, tb: TracebackType | None) -> None:
        await self._close()

    async def _close(self) -> None:
        # pollers finish their current poll (bounded by the device timeout) and return;
        # only a poller that does not is cancelled
        for p in self.pollers:
            p.stop()
        for t in self._tasks:
            if t.get_name() == "analysis":
                t.cancel()
        if self._tasks:
            grace = max((p.device.timeout_s for p in self.pollers), default=0.0) + 1.0
            _, pending = await asyncio.wait(self._tasks, timeout=grace)
            for t in pending:
                t.cancel()
            if pending:
                _, pending = await asyncio.wait(pending, timeout=1.0)
            for t in pending:
                log.error("task %s did not stop; abandoned", t.get_name())
        self._tasks.clear()
        if self._http is not None:
            server, thread = self._http
            server.shutdown()
            server.server_close()
            thread.join(timeout=5)
            self._http = None
        with contextlib.suppress(Exception):
            await self.result_server.stop()
        await self.scheduler.stop()


async def serve(config: Config, stop: asyncio.Event, **kwargs: Any) -> None:
    """Run a gateway until ``stop`` is set."""
    async with Gateway(config, **kwargs) as gw:
        log.info("gateway running: %d devices, %d loops; metrics on %s:%s, "
                 "Modbus results on %s:%s", len(config.devices), len(config.loops),
                 config.metrics.listen[0], gw.metrics_port,
                 config.modbus_server.listen[0], gw.result_port)
        await stop.wait()
        log.info("gateway stopping")


def install_stop_signals(stop: asyncio.Event) -> None:
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)


def run(config: Config) -> int:
    """``stiction-gateway run``: serve until SIGTERM/SIGINT; returns the exit status."""

    async def main() -> None:
        stop = asyncio.Event()
        install_stop_signals(stop)
        await serve(config, stop)

    asyncio.run(main())
    return 0
