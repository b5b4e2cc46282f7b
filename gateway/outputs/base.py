"""The interface every output implements: a :class:`Sink`, and what it is bound to.

A sink is a view of the running gateway: it is started once, bound to the current
:class:`Binding` (at start-up and after each reload), and stopped once. It never computes a
result: everything it publishes comes from the result store (and, for the state file, the
windows). An output plugin module (registered by one line in
:data:`gateway.config.plugins.OUTPUTS`) defines ``create_sink(binding, **options)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Awaitable, Callable
from typing import Protocol

from ..config.model import Config
from ..core.store import ResultStore
from ..core.ticks import ProcessClock
from ..core.windows import LoopGroup

__all__ = ["Binding", "Sink", "Swap"]


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
