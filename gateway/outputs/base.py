"""The interface every output implements: a :class:`Sink`, and what it is bound to.

A sink is a view of the running gateway: it is started once, bound to the current
:class:`Binding` (at start-up and after each reload), and stopped once. It never computes a
result: everything it publishes comes from the result store (and, for the state file, the
windows). An output plugin module (registered by one line in
:data:`gateway.config.plugins.OUTPUTS`) defines ``create_sink(binding, **options)``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import BinaryIO, Protocol

from ..config.model import Config
from ..core.store import ResultStore
from ..core.ticks import ProcessClock
from ..core.windows import LoopGroup

__all__ = ["Binding", "Sink", "Swap", "write_atomically"]


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
