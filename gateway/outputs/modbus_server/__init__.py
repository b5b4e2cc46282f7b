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
    """The gateway's result server. The images are kept from construction on; the TCP
    server exists from :meth:`start` to :meth:`stop`. :meth:`bind` serves a new config's
    loops; a new ``modbus_server`` section, or a unit id the running server was not built
    for, makes it build a new :class:`RegisterServer` (pymodbus fixes its devices when
    built): ``server`` is then another object."""

    def __init__(self, settings: ResultServerSettings, loops: Sequence[LoopConfig],
                 store: ResultStore) -> None:
        self.settings = settings
        self.images: dict[int, NDArray[np.uint16]] = {}
        self.units = frozenset(self.unit_ids_of(loops)) | {0}  # what the server is built for
        self.server: RegisterServer | None = None
        self.rebind(loops, store)

    def _new_server(self) -> RegisterServer:
        host, port = self.settings.listen
        return RegisterServer(units={u: {"holding": img, "input": img}
                                     for u, img in self.images.items()},
                              host=host, port=port, capacity=65536)  # blocks may move

    def unit_of(self, loop: LoopConfig) -> int:
        return self.settings.unit_id if loop.result_unit_id is None else loop.result_unit_id

    def unit_ids_of(self, loops: Sequence[LoopConfig]) -> set[int]:
        """The unit ids serving ``loops`` (always including modbus_server.unit_id)."""
        return {self.unit_of(lp) for lp in loops} | {self.settings.unit_id}

    def serves(self, loops: Sequence[LoopConfig]) -> bool:
        """Whether :meth:`rebind` can serve ``loops`` (no unit id new to this server)."""
        return self.unit_ids_of(loops) <= self.units

    @property
    def image(self) -> NDArray[np.uint16]:
        """The register image of modbus_server.unit_id."""
        return self.images[self.settings.unit_id]

    @property
    def port(self) -> int:
        return self.server.port if self.server is not None else self.settings.listen[1]

    def rebind(self, loops: Sequence[LoopConfig], store: ResultStore) -> None:
        """Serve ``loops`` from ``store`` from now on: fresh images, so the blocks of
        removed loops vanish (reads there get exception 2 or zeros) and unit ids no longer
        used get exception 0x0A."""
        if not self.serves(loops):
            raise ValueError(f"result unit ids {sorted(self.unit_ids_of(loops))} are not all "
                             f"served (built for {sorted(self.units - {0})})")
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
        if self.server is not None:
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
        if cfg.modbus_server == self.settings and self.serves(cfg.loops):
            self.rebind(cfg.loops, binding.store)
            return
        # new settings, or a result unit id the running server has no device for
        running = self.server is not None
        await self.stop()
        self.settings = cfg.modbus_server
        self.units = frozenset(self.unit_ids_of(cfg.loops)) | {0}
        self.rebind(cfg.loops, binding.store)
        if running:
            await self.start()

    async def start(self) -> None:
        server = self._new_server()
        await server.start()
        self.server = server

    async def stop(self) -> None:
        server, self.server = self.server, None
        if server is not None:
            await server.stop()
