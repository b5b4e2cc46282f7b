"""Verdict history output: which verdict each loop had on each day, kept beside the state file
(``gateway.state`` -> ``gateway.verdicts``) so the engineer's findings are compared with the
verdicts of their day across restarts and kills (:mod:`.history`, the file;
:class:`gateway.core.findings.VerdictHistory`, what it holds).

The sink loads the file when it starts (before the state file is restored, so restored
assessments extend the history; read off the event loop, bounded in time and size:
:mod:`gateway.config.reading`), writes it every ``gateway.persist_interval_s`` when it
changed and once more when it stops; a failing write is logged once, and once when it works
again. A file that cannot be used is set aside; the history starts afresh.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...config.findings import verdicts_path
from ...config.reading import bounded
from ...core.findings import FindingsBook
from ..base import Binding, PeriodicWrites, in_thread, remove_temporaries
from .history import HistoryError, read_history, set_aside, write_history

__all__ = ["VerdictFile", "create_sink", "read_history"]

log = logging.getLogger("gateway.state")


def create_sink(binding: Binding, *, findings: FindingsBook | None = None, **_: Any
                ) -> VerdictFile:
    return VerdictFile(binding, findings if findings is not None else FindingsBook())


class VerdictFile:
    """Loads on :meth:`start`, writes when changed every persist interval and on :meth:`stop`."""

    def __init__(self, binding: Binding, book: FindingsBook, *,
                 wall: Callable[[], float] = time.time) -> None:
        self.binding = binding
        self.book = book
        self.wall = wall
        self.saves = 0
        self.set_aside: Path | None = None
        self._lock = asyncio.Lock()
        self.writes = PeriodicWrites(
            "verdict history", lambda: self.path, self.save,
            lambda: self.binding.config.gateway.persist_interval_s, log=log,
            changed=lambda: self.book.history.dirty)

    @property
    def path(self) -> Path:
        return verdicts_path(self.binding.config.gateway.state_file)

    async def bind(self, binding: Binding) -> None:
        before = self.path
        self.binding = binding
        if self.path != before:
            log.warning("reload: the verdict history is written to %s from now on",
                        self.path)
            self.book.history.dirty = True

    async def start(self) -> None:
        loaded = await asyncio.to_thread(self.read)  # bounded in time: off the event loop
        if loaded is not None:
            self.book.history.load(loaded)
            self.book.refresh(force=True)
            log.info("verdict history %s: %d loops", self.path, len(self.book.history.loops))
        self.writes.start()

    def read(self) -> dict[str, Any] | None:
        """The history file's loops (None: none, or unusable: set aside, or left where it is
        when it could not be read), temporary files of a killed write removed; touches
        nothing of the running gateway."""
        p = self.path
        max_loops = 2 * len(self.binding.config.loops) + 1000
        try:
            if not bounded(remove_temporaries, p):
                return None
            return read_history(p, max_loops=max_loops)
        except OSError as exc:  # the folder did not answer in time
            log.error("verdict history %s: %s; the history starts afresh", p,
                      exc.strerror or exc)
            return None
        except HistoryError as exc:
            if exc.kind == "unreadable":
                log.error("verdict history %s: %s; the history starts afresh", p, exc)
                return None
            with contextlib.suppress(OSError):
                self.set_aside = set_aside(p, exc.kind)
            log.warning("verdict history %s: %s; set aside as %s, the history starts afresh",
                        p, exc, self.set_aside)
            return None

    async def save(self) -> int:
        """Write the history now (atomically); returns its size in bytes."""
        async with self._lock:
            history = self.book.history
            history.prune(dt.datetime.fromtimestamp(self.wall()).date())
            data, history.dirty = history.to_data(), False
            try:
                size = await in_thread(write_history, self.path, data, self.wall())
            except BaseException:
                history.dirty = True
                raise
            self.saves += 1
            return size

    async def stop(self) -> None:
        await self.writes.stop()
