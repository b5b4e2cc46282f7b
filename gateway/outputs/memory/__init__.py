"""In-memory output plugin: a sink that keeps what it is shown (for tests).

It records whether it was started and stopped, every binding, and every change the result
store announced, as ``(loop, verdict name)``; :meth:`MemorySink.snapshot` is the store now.
"""

from __future__ import annotations

from typing import Any

from ...core.store import StoreSnapshot
from ..base import Binding

__all__ = ["MemorySink", "create_sink"]


class MemorySink:
    def __init__(self) -> None:
        self.started = self.stopped = False
        self.bindings: list[Binding] = []
        self.changes: list[tuple[str, str]] = []

    async def start(self) -> None:
        self.started = True

    async def bind(self, binding: Binding) -> None:
        self.bindings.append(binding)
        store = binding.store

        def on_change(i: int) -> None:
            if self.bindings[-1].store is store:  # an old store no longer counts
                self.changes.append((store.loops[i], store.verdict_name(i)))

        store.subscribe(on_change)

    async def stop(self) -> None:
        self.stopped = True

    def snapshot(self) -> StoreSnapshot:
        return self.bindings[-1].store.snapshot()


def create_sink(binding: Binding, **_: Any) -> MemorySink:
    return MemorySink()
