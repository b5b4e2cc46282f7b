"""The interface every output implements: a :class:`Sink`, and what it is bound to.

A sink is a view of the running gateway: it is started once, bound to the current
:class:`Binding` (at start-up and after each reload), and stopped once. It never computes a
result: everything it publishes comes from the result store (and, for the state file, the
windows). An output plugin module (registered by one line in
:data:`gateway.config.plugins.OUTPUTS`) defines ``create_sink(binding, **options)``.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime as dt
import logging
import os
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, BinaryIO, Protocol, TypeVar

from ..config.model import Config
from ..core.store import ResultStore
from ..core.ticks import ProcessClock
from ..core.windows import LoopGroup

__all__ = ["Binding", "PeriodicWrites", "Sink", "Swap", "check_days", "in_thread",
           "remove_temporaries", "set_aside", "write_atomically"]

T = TypeVar("T")


@dataclasses.dataclass(frozen=True)
class Binding:
    """What sinks serve: the running config, its loop groups (windows; each loop's row in
    the store), the result store and the process clock. A reload makes a new one."""

    config: Config
    groups: tuple[LoopGroup, ...]
    store: ResultStore
    clock: ProcessClock


@dataclasses.dataclass(frozen=True)
class Swap:
    """What a sink prepared for a reload (e.g. a server bound on its new address):
    ``commit()`` puts it in service, ``abort()`` closes it (the reload was refused)."""

    commit: Callable[[], Awaitable[None]]
    abort: Callable[[], Awaitable[None]]


class Sink(Protocol):
    """One output. ``bind`` may be called before ``start`` and any number of times after.

    A sink with a listener may also define ``async prepare(config) -> Swap | None``: a
    reload calls it on every sink before it changes anything and refuses the new config if
    one raises OSError (an address in use), so the running one keeps serving."""

    async def start(self) -> None:
        """Open what the output needs (a server, a file); raise OSError if it cannot."""

    async def bind(self, binding: Binding) -> None:
        """Serve ``binding`` from now on (loops removed by a reload vanish)."""

    async def stop(self) -> None:
        """Flush and close; never raises."""


def write_atomically(path: str | os.PathLike[str], write: Callable[[BinaryIO], None]) -> int:
    """Write a file so that a crash (even SIGKILL) leaves the old one or the new one:
    ``write(f)`` fills a temporary file in the same folder (``.NAME.tmp-PID``), which is
    ``fsync``'d and renamed over ``path``, then the folder is ``fsync``'d. Returns the
    bytes written (the state file and the verdict history both write so)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
            size = f.tell()
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    with contextlib.suppress(OSError):  # not every file system lets a directory be synced
        fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return size


async def in_thread(write: Callable[..., T], *args: object) -> T:
    """``write(*args)`` in a thread, awaited; cancelled, the thread still finishes its file
    before the cancellation goes on (so the next write, e.g. the last one at stop, never
    shares its temporary file)."""
    job = asyncio.ensure_future(asyncio.to_thread(write, *args))
    try:
        return await asyncio.shield(job)
    except asyncio.CancelledError:
        await asyncio.wait([job])
        raise


class PeriodicWrites:
    """The write schedule of an output that keeps a file (the state file, the verdict
    history): ``save()`` every ``interval()`` seconds (read each time: a reload may change
    it) when ``changed()``; a failing write calls ``failed()`` and is logged once, and once
    when writes work again (a full disk must not stop the gateway); :meth:`stop` ends the
    schedule and writes once more (``save(**final)``), never raising."""

    def __init__(self, what: str, path: Callable[[], object],
                 save: Callable[..., Awaitable[int]], interval: Callable[[], float], *,
                 log: logging.Logger, changed: Callable[[], bool] = lambda: True,
                 failed: Callable[[], None] = lambda: None) -> None:
        self.what, self.path, self.save, self.interval = what, path, save, interval
        self.log, self.changed, self.failed = log, changed, failed
        self._task: asyncio.Task[None] | None = None

    @property
    def running(self) -> bool:
        return self._task is not None

    def start(self) -> None:
        self._task = asyncio.create_task(self._run(), name=f"persist {self.what}")

    async def _run(self) -> None:
        failing = False
        while True:
            interval = self.interval()
            await asyncio.sleep(interval)
            if not self.changed():
                continue
            try:
                await self.save()
            except Exception as exc:
                self.failed()
                if not failing:
                    self.log.error("%s %s: write failed: %s (retrying every %g s)",
                                   self.what, self.path(), exc, interval)
                failing = True
            else:
                if failing:
                    self.log.warning("%s %s: writing again", self.what, self.path())
                failing = False

    async def stop(self, **final: object) -> None:
        """End the schedule and write the last time; nothing if it never started (nothing
        was loaded: nothing to write over the old file)."""
        if self._task is None:
            return
        self._task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._task
        self._task = None
        try:
            await self.save(**final)
        except Exception:
            self.failed()
            self.log.exception("%s: final write failed", self.what)


def set_aside(path: Path, kind: str) -> Path:
    """Move a file that cannot be used out of the way: ``NAME.KIND-YYYYmmddTHHMMSS``."""
    dest = path.with_name(f"{path.name}.{kind}-{time.strftime('%Y%m%dT%H%M%S')}")
    os.replace(path, dest)
    return dest


def remove_temporaries(p: Path) -> bool:
    """Remove the temporary files a write killed half-way left beside ``p``
    (:func:`write_atomically`'s); whether ``p`` exists."""
    for tmp in p.parent.glob(f".{p.name}.tmp-*"):
        with contextlib.suppress(OSError):
            tmp.unlink()
    return p.exists()


_FIRST_DAY, _LAST_DAY = dt.date(1970, 1, 1).toordinal(), dt.date(9999, 12, 31).toordinal()


def check_days(days: list[Any], where: str) -> None:
    """A file's list of days: ``YYYY-MM-DD`` texts, 1970 .. 9999, each after the one before
    (ValueError naming the first that is not)."""
    last = _FIRST_DAY - 1
    for k, day in enumerate(days):
        try:
            ordinal = dt.date.fromisoformat(day).toordinal() if isinstance(day, str) \
                and len(day) == 10 else None
        except ValueError:
            ordinal = None
        if ordinal is None or not last < ordinal <= _LAST_DAY:
            raise ValueError(f"{where}.days[{k}]: not a date after the one before")
        last = ordinal
