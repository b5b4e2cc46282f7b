"""Modbus result server output (the ``modbus_server`` config section): a read-only view of
the result store as registers.

One block per loop at its ``result_address`` on its ``result_unit_id`` (the layout is
:mod:`gateway.wire.results`, docs/modbus-map.md), one image per unit id, the same image in
holding and input registers, refreshed on every change the store announces. Unit ids no loop
uses answer exception 0x0A; writes answer exception 1 (:mod:`gateway.wire.registers`). The
server bounds its connections (``max_connections``, ``idle_timeout_s``), counted in the
metrics as ``server="modbus"``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...config.model import Config, LoopConfig, ResultServerSettings
from ...core.store import ResultStore
from ...wire.listener import ListenerStats
from ...wire.registers import RegisterServer
from ...wire.results import NO_SOURCE_ADDRESS, result_block, unit_images, verdict_code
from ..base import Binding, Swap

__all__ = ["ResultServer", "create_sink"]


def create_sink(binding: Binding, *, metrics: Any = None, **_: Any) -> ResultServer:
    server = ResultServer(binding.config.modbus_server, binding.config.loops, binding.store)
    if metrics is not None:
        metrics.track_server("modbus", server.stats)
    return server


class ResultServer:
    """The gateway's result server. The images are kept from construction on; the TCP
    server exists from :meth:`start` to :meth:`stop`. :meth:`bind` serves a new config's
    loops and unit ids on the running server; a new ``listen`` address needs a new server,
    bound by :meth:`prepare` before a reload swaps (``server`` is then another object)."""

    def __init__(self, settings: ResultServerSettings, loops: Sequence[LoopConfig],
                 store: ResultStore) -> None:
        self.settings = settings
        self.images: dict[int, NDArray[np.uint16]] = {}
        self.server: RegisterServer | None = None
        self._listen = settings.listen  # the address the running server was asked for
        self.stats = ListenerStats()  # connections, over every server this output runs
        self.rebind(loops, store)

    def _new_server(self, settings: ResultServerSettings) -> RegisterServer:
        host, port = settings.listen
        return RegisterServer(units=self._units(), host=host, port=port,
                              max_connections=settings.max_connections,
                              idle_timeout_s=settings.idle_timeout_s,
                              identification=dict(settings.identification), stats=self.stats)

    def _units(self) -> dict[int, dict[str, NDArray[np.uint16]]]:
        return {u: {"holding": img, "input": img} for u, img in self.images.items()}

    def unit_of(self, loop: LoopConfig) -> int:
        return self.settings.unit_id if loop.result_unit_id is None else loop.result_unit_id

    def unit_ids_of(self, loops: Sequence[LoopConfig]) -> set[int]:
        """The unit ids serving ``loops`` (always including modbus_server.unit_id)."""
        return {self.unit_of(lp) for lp in loops} | {self.settings.unit_id}

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
        self.store = store
        self.size = self.settings.block_registers
        self.addresses = np.array([lp.result_address for lp in loops], dtype=np.intp)
        units = [self.unit_of(lp) for lp in loops]
        # each loop's block, by name: the extended block names a group's source by it
        self._block_of = {lp.name: (u, int(lp.result_address))
                          for lp, u in zip(loops, units, strict=True)}
        used: dict[int, list[int]] = {u: [] for u in self.unit_ids_of(loops)}
        for u, a in zip(units, self.addresses.tolist(), strict=True):
            used[u].append(a)
        self.images = unit_images(used, self.size)
        self._image_of = [self.images[u] for u in units]  # per loop, for refresh
        for i in range(len(loops)):
            self.refresh(i)
        if self.server is not None:
            self.server.units = self._units()

        def on_change(i: int) -> None:
            if self.store is store:  # an old store (before a reload) no longer counts
                self.refresh(i)

        store.subscribe(on_change)

    def refresh(self, i: int) -> None:
        a = int(self.addresses[i])
        st = self.store
        code = verdict_code(st.results[i], bool(st.stale[i]), bool(st.down[i]))
        source = st.plant.of(st.loops[i])[2]
        self._image_of[i][a:a + self.size] = result_block(
            st.results[i], code=code, word_order=self.settings.word_order,
            plant=st.plant_registers(i), size=self.size,
            source=self._block_of.get(source or "", (0, NO_SOURCE_ADDRESS)),
            rank=(int(st.rank[i]), float(st.suspicion[i])))

    async def prepare(self, config: Config) -> Swap | None:
        """Bind the new ``listen`` address, if it moved, before a reload swaps (OSError if
        it is in use: the reload is refused and this server keeps serving)."""
        new = config.modbus_server
        if self.server is None or new.listen == self._listen:
            return None
        server = self._new_server(new)
        await server.open()

        async def commit() -> None:  # serve on the new address, then let the old one go
            await server.start()
            old, self.server, self._listen = self.server, server, new.listen
            if old is not None:
                await old.stop()

        return Swap(commit, server.stop)

    async def bind(self, binding: Binding) -> None:
        cfg = binding.config.modbus_server
        self.settings = cfg
        self.rebind(binding.config.loops, binding.store)
        server = self.server
        if server is None:
            return
        if cfg.listen != self._listen:  # not prepared (bound outside a reload): move now
            swap = await self.prepare(binding.config)
            if swap is not None:
                await swap.commit()
        server.listener.max_connections = cfg.max_connections
        server.listener.idle_timeout_s = cfg.idle_timeout_s
        server.set_identification(dict(cfg.identification))

    async def start(self) -> None:
        server = self._new_server(self.settings)
        await server.start()
        self.server, self._listen = server, self.settings.listen

    async def stop(self) -> None:
        server, self.server = self.server, None
        if server is not None:
            await server.stop()
