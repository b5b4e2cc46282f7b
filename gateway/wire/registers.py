"""Read-only Modbus TCP servers over a numpy register image (pymodbus 3.16 SimDevice API).

:class:`RegisterServer` serves one uint16 image per table through a ``SimDevice`` action
hook: each read copies just the requested slice of the image into pymodbus' registers, so
updating the image is a numpy assignment and never goes through pymodbus. Writes can be
refused (exception 1, illegal function). It also counts the requests it served, which the
tests use to prove that the gateway coalesces its reads.

:class:`ResultServer` is the gateway's result server: one 20-register block per loop at
its ``result_address`` on its ``result_unit_id`` (docs/modbus-map.md), one image per unit
id, the same image in holding and input registers, refreshed from the
:class:`~gateway.store.ResultStore` on every change.

Both servers are read-only: every write (function codes 5, 6, 15, 16, 22, 23) and every
coil/discrete-input read is answered with exception 1 (illegal function).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from ..config import RESULT_BLOCK_SIZE, LoopConfig, ResultServerSettings
from ..core.store import LoopResult, ResultStore
from ..inputs.modbus.client import encode_values

__all__ = ["RegisterServer", "ResultServer", "result_block"]

log = logging.getLogger("gateway.result_server")

READ_CODES = {3: "holding", 4: "input"}


class RegisterServer:
    """A Modbus TCP server answering reads from uint16 register images, per unit id.

    ``units`` maps each served unit id to its images by table (``{"holding": img,
    "input": img}``; one array may serve both tables); the one-unit form
    ``RegisterServer(images, unit_id=...)`` is ``units={unit_id: images}``. ``self.units``
    may be replaced (or its images swapped) while serving, but only for the unit ids given
    at construction: pymodbus fixes its devices when the server is built. Unit id 0 is the
    catch-all: requests for a unit id without a device go to it, so ``unit_id=0`` answers
    every id; any unit id not (or no longer) in ``self.units`` gets exception 0x0A (gateway
    path unavailable). Writes are refused with exception 1 (illegal function) and counted
    in ``refused_writes``."""

    def __init__(self, images: dict[str, NDArray[np.uint16]] | None = None, *, host: str,
                 port: int, unit_id: int = 1, capacity: int | None = None,
                 units: Mapping[int, dict[str, NDArray[np.uint16]]] | None = None) -> None:
        if units is None:
            if images is None:
                raise TypeError("RegisterServer needs images or units")
            units = {unit_id: images}
        self.units: dict[int, dict[str, NDArray[np.uint16]]] = dict(units)
        self.unit_id = unit_id if images is not None else min(self.units)
        self.requests = 0  # read requests answered from the image
        self.refused_writes = 0
        self.host, self.port = host, port
        # the address range pymodbus accepts; images may be swapped for larger ones up to it
        size = capacity or max(len(img) for imgs in self.units.values()
                               for img in imgs.values())
        self.unit_ids = frozenset(self.units) | {0}  # the devices pymodbus knows
        devices = [self._device(unit, size, self._action_for(unit))
                   for unit in sorted(self.unit_ids)]
        self._server = ModbusTcpServer(devices, address=(host, port))

    @property
    def images(self) -> dict[str, NDArray[np.uint16]]:
        """The images of the unit id given at construction (the one-unit form)."""
        return self.units[self.unit_id]

    @staticmethod
    def _device(unit: int, size: int, action: object) -> SimDevice:
        def block() -> list[SimData]:
            return [SimData(0, count=size, datatype=DataType.REGISTERS)]

        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        return SimDevice(id=unit, simdata=(bits, list(bits), block(), block()),
                         action=action)  # type: ignore[arg-type]

    def _action_for(self, unit: int) -> object:
        async def action(function_code: int, start: int, address: int, count: int,  # noqa: PLR0917 (pymodbus SimAction)
                         registers: list[int], values: object) -> ExcCodes | None:
            return self._serve(unit, function_code, start, address, count, registers, values)

        return action

    def _serve(self, unit: int, function_code: int, start: int, address: int,  # noqa: PLR0917
               count: int, registers: list[int], values: object) -> ExcCodes | None:
        images = self.units.get(unit)
        if images is None:  # a unit id nobody serves (any more)
            return ExcCodes.GATEWAY_PATH_UNAVIABLE
        table = READ_CODES.get(function_code)
        if values is not None or table is None:  # any write, or a bit read
            self.refused_writes += values is not None
            return ExcCodes.ILLEGAL_FUNCTION
        self.requests += 1
        img = images.get(table)
        if img is None or address + count > len(img):
            return ExcCodes.ILLEGAL_ADDRESS
        off = address - start
        registers[off:off + count] = img[address:address + count].tolist()
        return None

    async def start(self) -> None:
        await self._server.serve_forever(background=True)
        sock = self._server.transport.sockets[0]  # type: ignore[attr-defined]
        self.port = sock.getsockname()[1]

    async def stop(self) -> None:
        await self._server.shutdown()  # type: ignore[no-untyped-call]


def result_block(loop_result: LoopResult | None, *, code: int, word_order: str = "big"
                 ) -> NDArray[np.uint16]:
    """The 20 registers of one loop (see docs/modbus-map.md)."""
    block = np.zeros(RESULT_BLOCK_SIZE, dtype=np.uint16)
    block[0] = code
    if loop_result is None:
        return block
    a = loop_result.assessment

    def f(x: float | None, factor: float = 1.0) -> float:
        return math.nan if x is None else float(x) * factor

    block[1] = loop_result.seq % 65536
    floats = [f(a.stiction_index), f(a.fd, 100.0), f(a.fs, 100.0), f(a.period_s),
              f(a.jump, 100.0)]
    block[2:12] = encode_values(floats, "float32", word_order).reshape(-1)
    block[12:14] = encode_values([max(0, int(loop_result.t))], "uint32", word_order)[0]
    block[14:16] = encode_values([loop_result.window_fill], "float32", word_order)[0]
    return block


class ResultServer:
    """The gateway's read-only result server, a view of the result store.

    Each unit id used by some loop (``result_unit_id``, default ``modbus_server.unit_id``)
    has its own register image, served alike as holding and input registers; other unit
    ids get exception 0x0A. :meth:`rebind` serves a new loop list from then on, as long as
    it uses no unit id the server was not built for (:meth:`serves`); otherwise the owner
    builds a new server (pymodbus fixes its devices when the server is built)."""

    def __init__(self, settings: ResultServerSettings, loops: Sequence[LoopConfig],
                 store: ResultStore) -> None:
        self.settings = settings
        self.images: dict[int, NDArray[np.uint16]] = {}
        host, port = settings.listen
        units = self.unit_ids_of(loops)
        placeholder = np.zeros(RESULT_BLOCK_SIZE, dtype=np.uint16)
        self.server = RegisterServer(
            units={u: {"holding": placeholder, "input": placeholder} for u in units},
            host=host, port=port,
            capacity=65536)  # a reload may move blocks anywhere
        self.rebind(loops, store)

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

    def rebind(self, loops: Sequence[LoopConfig], store: ResultStore) -> None:
        """Serve ``loops`` from ``store`` from now on (start-up and reload): fresh images,
        so the blocks of removed loops vanish (reads there get exception 2 or zeros) and
        unit ids no longer used get exception 0x0A."""
        if not self.serves(loops):
            raise ValueError(f"result unit ids {sorted(self.unit_ids_of(loops))} are not all "
                             f"served (built for {sorted(self.server.unit_ids - {0})})")
        self.store = store
        self.addresses = np.array([lp.result_address for lp in loops], dtype=np.intp)
        units = [self.unit_of(lp) for lp in loops]
        ends: dict[int, int] = dict.fromkeys(self.unit_ids_of(loops), RESULT_BLOCK_SIZE)
        for u, a in zip(units, self.addresses.tolist(), strict=True):
            ends[u] = max(ends[u], a + RESULT_BLOCK_SIZE)
        images = {u: np.zeros(end, dtype=np.uint16) for u, end in ends.items()}
        self.images = images
        self._image_of = [images[u] for u in units]  # per loop, for refresh
        for i in range(len(loops)):
            self.refresh(i)
        self.server.units = {u: {"holding": img, "input": img} for u, img in images.items()}

        def on_change(i: int) -> None:
            if self.store is store:  # an old store (before a reload) no longer counts
                self.refresh(i)

        store.subscribe(on_change)

    @property
    def port(self) -> int:
        return self.server.port

    def refresh(self, i: int) -> None:
        a = int(self.addresses[i])
        self._image_of[i][a:a + RESULT_BLOCK_SIZE] = result_block(
            self.store.results[i], code=self.store.verdict_code(i),
            word_order=self.settings.word_order)

    async def start(self) -> None:
        await self.server.start()

    async def stop(self) -> None:
        await self.server.stop()
