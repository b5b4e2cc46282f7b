"""Modbus result server output (the ``modbus_server`` config section): a read-only view of
the result store as registers.

One block per loop at its ``result_address`` on its ``result_unit_id`` (the layout is
:mod:`gateway.wire.results`, docs/modbus-map.md), one image per unit id, the same image in
holding and input registers, refreshed on every change the store announces. Unit ids no loop
uses answer exception 0x0A; writes answer exception 1 (:mod:`gateway.wire.registers`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...config.model import LoopConfig, ResultServerSettings
from ...core.store import ResultStore
from ...wire.registers import RegisterServer
from ...wire.results import RESULT_BLOCK_SIZE, result_block, unit_images, verdict_code
from ..base import Binding

__all__ = ["ResultServer", "create_sink"]


def create_sink(binding: Binding, **_: Any) -> ResultServer:
    return ResultServer(binding.config.modbus_server, binding.config.loops, binding.store)


class ResultServer:
    """The gateway's result server. :meth:`bind` serves a new config's loops; a new
    ``modbus_server`` section, or a unit id the running server was not built for, makes it
    build a new :class:`RegisterServer` (pymodbus fixes its devices when built): ``server``
    is then another object."""

    def __init__(self, settings: ResultServerSettings, loops: Sequence[LoopConfig],
                 store: ResultStore) -> None:
        self.settings = settings
        self.images: dict[int, NDArray[np.uint16]] = {}
        self.server = self._new_server(loops)
        self.started = False
        self.rebind(loops, store)

    def _new_server(self, loops: Sequence[LoopConfig]) -> RegisterServer:
        host, port = self.settings.listen
        placeholder = np.zeros(RESULT_BLOCK_SIZE, dtype=np.uint16)
        return RegisterServer(
            units={u: {"holding": placeholder, "input": placeholder}
                   for u in self.unit_ids_of(loops)},
            host=host, port=port, capacity=65536)  # a reload may move blocks anywhere

    def unit_of(self, loop: LoopConfig) -> int:
        return self.settings.unit_id if loop.result_unit_id is None else loop.result_unit_id

    def unit_ids_of(self, loops: Sequence[LoopConfig]) -> set[int]:
        """The unit ids serving ``loops`` (always including modbus_server.unit_id)."""
        return {self.unit_of(lp) for lp in loops} | {self.settings.unit_id}

    def serves(self, loops: Sequence[LoopConfig]) -> bool:
        """Whether :meth:`rebind` can serve ``loops`` (no unit id new to this server)."""
        return self.unit_ids_of(loops) <= self.server.unit_ids

    @property
    def image(self) -> NDArray[np.uint16]:
        """The register image of modbus_server.unit_id."""
        return self.images[self.settings.unit_id]

    @property
    def port(self) -> int:
        return self.server.port

    def rebind(self, loops: Sequence[LoopConfig], store: ResultStore) -> None:
        """Serve ``loops`` from ``store`` from now on: fresh images, so the blocks of
        removed loops vanish (reads there get exception 2 or zeros) and unit ids no longer
        used get exception 0x0A."""
        if not self.serves(loops):
            raise ValueError(f"result unit ids {sorted(self.unit_ids_of(loops))} are not all "
                             f"served (built for {sorted(self.server.unit_ids - {0})})")
        self.store = store
        self.addresses = np.array([lp.result_address for lp in loops], dtype=np.intp)
        units = [self.unit_of(lp) for lp in loops]
        used: dict[int, list[int]] = {u: [] for u in self.unit_ids_of(loops)}
        for u, a in zip(units, self.addresses.tolist(), strict=True):
            used[u].append(a)
        self.images = unit_images(used)
        self._image_of = [self.images[u] for u in units]  # per loop, for refresh
        for i in range(len(loops)):
            self.refresh(i)
        self.server.units = {u: {"holding": img, "input": img}
                             for u, img in self.images.items()}

        def on_change(i: int) -> None:
            if self.store is store:  # an old store (before a reload) no longer counts
                self.refresh(i)

        store.subscribe(on_change)

    def refresh(self, i: int) -> None:
        a = int(self.addresses[i])
        st = self.store
        self._image_of[i][a:a + RESULT_BLOCK_SIZE] = result_block(
            st.results[i], code=verdict_code(st.results[i], bool(st.stale[i])),
            word_order=self.settings.word_order)

    async def bind(self, binding: Binding) -> None:
        cfg = binding.config
        if cfg.modbus_server != self.settings or not self.serves(cfg.loops):
            # new settings, or a result unit id the running server has no device for
            if self.started:
                await self.server.stop()
            self.settings = cfg.modbus_server
            self.server = self._new_server(cfg.loops)
            self.rebind(cfg.loops, binding.store)
            if self.started:
                await self.server.start()
        else:
            self.rebind(cfg.loops, binding.store)

    async def start(self) -> None:
        await self.server.start()
        self.started = True

    async def stop(self) -> None:
        if self.started:
            self.started = False
            await self.server.stop()
