"""The site calibration output: each loop's confidence on each day and the calibration fitted
on the crew's findings, kept beside the state file (``gateway.state`` ->
``gateway.calibration``, :mod:`.file`) so that the fit and what it was fitted on survive a
restart (:class:`gateway.core.sitecal.SiteBook`).

The sink loads the file when it starts (off the event loop, bounded in time and size: the
calibration read back is in force at once, until the gateway fits again), writes it every
``gateway.persist_interval_s`` when it changed and once more when it stops; a failing write
is logged once. A file that cannot be used is set aside and the history starts afresh.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...config.reading import bounded
from ...core.sitecal import SiteBook, SiteView, state_of
from ..base import Binding, PeriodicWrites, in_thread, remove_temporaries, set_aside
from .file import CalibrationError, calibration_path, read_calibration, write_calibration

__all__ = ["CalibrationFile", "calibration_path", "create_sink", "read_calibration"]

log = logging.getLogger("gateway.state")


def create_sink(binding: Binding, *, site: SiteBook | None = None, **_: Any
                ) -> CalibrationFile:
    return CalibrationFile(binding, site if site is not None else SiteBook())


class CalibrationFile:
    """Loads on :meth:`start`, writes when changed every persist interval and on
    :meth:`stop`."""

    def __init__(self, binding: Binding, site: SiteBook, *,
                 wall: Callable[[], float] = time.time) -> None:
        self.binding = binding
        self.site = site
        self.wall = wall
        self.saves = 0
        self.set_aside: Path | None = None
        self._saved_view: SiteView | None = None
        self._lock = asyncio.Lock()
        self.writes = PeriodicWrites(
            "site calibration", lambda: self.path, self.save,
            lambda: self.binding.config.gateway.persist_interval_s, log=log,
            changed=lambda: self.site.history.dirty or self.site.view is not self._saved_view)

    @property
    def path(self) -> Path:
        return calibration_path(self.binding.config.gateway.state_file)

    async def bind(self, binding: Binding) -> None:
        before = self.path
        self.binding = binding
        if self.path != before:
            log.warning("reload: the site calibration is written to %s from now on",
                        self.path)
            self.site.history.dirty = True

    async def start(self) -> None:
        got = await asyncio.to_thread(self.read)
        if got is not None:
            loops, calibration, fitted = got
            self.site.history.load(loops)
            enabled = self.binding.config.analysis.site_calibration
            self.site.view = SiteView(calibration, state_of(calibration, enabled), fitted)
            self._saved_view = self.site.view
            log.info("site calibration %s: %s calibration (%s), confidences of %d loops",
                     self.path, calibration.name, calibration.why, len(loops))
        self.writes.start()

    def read(self) -> Any:
        """``(loops, calibration, fitted)`` of the file, or None (none, or unusable: set
        aside, or left where it is when it could not be read)."""
        p = self.path
        max_loops = 2 * len(self.binding.config.loops) + 1000
        try:
            if not bounded(remove_temporaries, p):
                return None
            return read_calibration(p, max_loops=max_loops)
        except OSError as exc:
            log.error("site calibration %s: %s; starting afresh", p, exc.strerror or exc)
            return None
        except CalibrationError as exc:
            if exc.kind == "unreadable":
                log.error("site calibration %s: %s; starting afresh", p, exc)
                return None
            with contextlib.suppress(OSError):
                self.set_aside = set_aside(p, exc.kind)
            log.warning("site calibration %s: %s; set aside as %s, starting afresh", p, exc,
                        self.set_aside)
            return None

    async def save(self) -> int:
        """Write the file now (atomically); returns its size in bytes."""
        async with self._lock:
            site = self.site
            view = site.view
            names = set(self.binding.store.loops)  # the config's loops only: a removed
            data = {k: v for k, v in site.history.to_data().items() if k in names}  # goes
            site.history.dirty = False
            try:
                size = await in_thread(write_calibration, self.path, data, view.calibration,
                                       view.fitted, self.wall())
            except BaseException:
                site.history.dirty = True
                raise
            self._saved_view = view
            self.saves += 1
            return size

    async def stop(self) -> None:
        await self.writes.stop()
