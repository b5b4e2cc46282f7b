"""The daemon around a :class:`~gateway.runtime.gateway.Gateway`: signals, sd_notify, watchdog.

:func:`run` is the ``stiction-gateway run`` entry: it runs until SIGTERM or SIGINT, reloads
on SIGHUP and speaks the systemd notify protocol (READY, STATUS, WATCHDOG only while every
poller makes progress, RELOADING, STOPPING). See docs/reliability.md.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import resource
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..config import Config
from ..config.checks import fds_needed
from .gateway import Gateway
from .logs import loop_exception_handler
from .sdnotify import Notifier, watchdog_interval

__all__ = ["Watchdog", "install_stop_signals", "raise_fd_limit", "run", "serve"]

log = logging.getLogger("gateway.app")


class Watchdog:
    """WATCHDOG=1 while every poller makes progress; silence otherwise, so systemd restarts
    a gateway whose polling hangs. One log line when the pings stop, one when they resume."""

    def __init__(self, gw: Gateway, notifier: Notifier) -> None:
        self.gw = gw
        self.notifier = notifier
        self.stalled: list[str] = []

    def step(self, now: float) -> bool:
        """Ping if no poller is stalled at loop time ``now``; True if it pinged."""
        stalled = self.gw.stalled_pollers(now)
        if not stalled:
            self.notifier.watchdog()
            if self.stalled:
                log.warning("polling progresses again; watchdog pings resumed")
        elif stalled != self.stalled:
            log.error("polling stalled for %s; withholding the watchdog ping",
                      ", ".join(stalled))
        self.stalled = stalled
        return not stalled


async def _watchdog(gw: Gateway, notifier: Notifier, interval: float) -> None:
    dog = Watchdog(gw, notifier)
    loop = asyncio.get_running_loop()
    while True:
        await asyncio.sleep(interval)
        dog.step(loop.time())


async def serve(config: Config, stop: asyncio.Event, *, reload: asyncio.Event | None = None,
                config_path: str | os.PathLike[str] | None = None,
                notifier: Notifier | None = None,
                on_started: Callable[[Gateway], None] | None = None, **kwargs: Any) -> None:
    """Run a gateway until ``stop`` is set; each time ``reload`` is set, reload the config
    from ``config_path``."""
    notifier = notifier or Notifier(address="")
    # an exception that reaches the event loop is logged by place and type, rate-limited
    asyncio.get_running_loop().set_exception_handler(loop_exception_handler)
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
                    if await gw.reload(path):
                        raise_fd_limit(gw.config)  # e.g. more devices
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


def raise_fd_limit(config: Config) -> int:
    """Raise the soft limit of open files to what ``config`` may need (at most the hard
    limit, ``LimitNOFILE`` of the unit: check-config refuses a config that needs more);
    returns the soft limit now in force."""
    need = fds_needed(config)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= need:
        return int(soft)
    new = need if hard == resource.RLIM_INFINITY else min(need, hard)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_NOFILE, (new, hard))
        log.info("open files limit raised from %d to %d", soft, new)
        return new
    return int(soft)


def run(config: Config, config_path: str | os.PathLike[str] | None = None) -> int:
    """``stiction-gateway run``: serve until SIGTERM/SIGINT, reload on SIGHUP, keep the
    state file; returns the exit status."""
    raise_fd_limit(config)

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
