"""The interface every output implements: a :class:`Sink`, and what it is bound to.

A sink is a view of the running gateway: it is started once, bound to the current
:class:`Binding` (at start-up and after each reload), and stopped once. It never computes a
result: everything it publishes comes from the result store (and, for the state file, the
windows). An output plugin module (registered by one line in
:data:`gateway.config.plugins.OUTPUTS`) defines ``create_sink(binding, **options)``.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

from ..config.model import Config
from ..core.store import ResultStore
from ..core.ticks import ProcessClock
from ..core.windows import LoopGroup

__all__ = ["Binding", "Sink"]


@dataclasses.dataclass(frozen=True)
class Binding:
    """What sinks serve: the running config, its loop groups (windows; each loop's row in
    the store), the result store and the process clock. A reload makes a new one."""

    config: Config
    groups: tuple[LoopGroup, ...]
    store: ResultStore
    clock: ProcessClock


class Sink(Protocol):
    """One output. ``bind`` may be called before ``start`` and any number of times after."""

    async def start(self) -> None:
        """Open what the output needs (a server, a file); raise OSError if it cannot."""

    async def bind(self, binding: Binding) -> None:
        """Serve ``binding`` from now on (loops removed by a reload vanish)."""

    async def stop(self) -> None:
        """Flush and close; never raises."""
