"""Read-only Modbus TCP servers over a numpy register image (pymodbus 3.16 SimDevice API).

:class:`RegisterServer` serves one uint16 image per table through a ``SimDevice`` action
hook: each read copies just the requested slice of the image into pymodbus' registers, so
updating the image is a numpy assignment and never goes through pymodbus. Writes can be
refused (exception 1, illegal function). It also counts the requests it served, which the
tests use to prove that the gateway coalesces its reads.

:class:`ResultServer` is the gateway's result server: one 20-register block per loop at
its ``result_address`` (docs/modbus-map.md), the same image in holding and input
registers, refreshed from the :class:`~gateway.store.ResultStore` on every change.

Both servers are read-only: every write (function codes 5, 6, 15, 16, 22, 23) and every
coil/discrete-input read is answered with exception 1 (illegal function).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .config import RESULT_BLOCK_SIZE, LoopConfig, ResultServerSettings
from .inputs.modbus import encode_values
from .store import LoopResult, ResultStore

__all__ = ["RegisterServer", "ResultServer", "result_block"]

log = logging.getLogger(__name__)

READ_CODES = {3: "holding", 4: "input"}


class RegisterServer:
    """A Modbus TCP server answering reads from ``images[table]`` (uint16 arrays).

    ``shared=True`` serves one image for both tables. Unit ids other than ``unit_id`` get
    exception 0x0A (gateway path unavailable); ``unit_id=0`` answers every id. Writes are
    refused with exception 1 (illegal function) and counted in ``refused_writes``."""

    def __init__(self, images: dict[str, NDArray[np.uint16]], *, host: str, port: int,
                 unit_id: int = 1) -> None:
        self.images = images
        self.requests = 0  # read requests answered from the image
        self.refused_writes = 0
        self.host, self.port = host, port
        size = max(len(img) for img in images.values())
        devices = [self._device(unit_id, size, self._action)]
        if unit_id != 0:
            devices.append(self._device(0, size, self._wrong_unit))
        self._server = ModbusTcpServer(devices, address=(host, port))

    @staticmethod
    def _device(unit: int, size: int, action: object) -> SimDevice:
        def block() -> list[SimData]:
            return [SimData(0, count=size, datatype=DataType.REGISTERS)]

        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        return SimDevice(id=unit, simdata=(bits, list(bits), block(), block()),
                         action=action)  # type: ignore[arg-type]

    async def _action(self, function_code: int, start: int, address: int, count: int,  # noqa: PLR0917 (pymodbus SimAction)
                      registers: list[int], values: object) -> ExcCodes | None:
        table = READ_CODES.get(function_code)
        if values is not None or table is None:  # any write, or a bit read
            self.refused_writes += values is not None
            return ExcCodes.ILLEGAL_FUNCTION
        self.requests += 1
        img = self.images.get(table)
        if img is None or address + count > len(img):
            return ExcCodes.ILLEGAL_ADDRESS
        off = address - start
        registers[off:off + count] = img[address:address + count].tolist()
        return None

    async def _wrong_unit(self, *_: object) -> ExcCodes | None:
        return ExcCodes.GATEWAY_PATH_UNAVIABLE

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
    """The gateway's read-only result server, a view of the result store."""

    def __init__(self, settings: ResultServerSettings, loops: Sequence[LoopConfig],
                 store: ResultStore) -> None:
        self.settings = settings
        self.store = store
        self.addresses = np.array([lp.result_address for lp in loops], dtype=np.intp)
        size = int(self.addresses.max()) + RESULT_BLOCK_SIZE if len(loops) else RESULT_BLOCK_SIZE
        self.image = np.zeros(size, dtype=np.uint16)
        host, port = settings.listen
        self.server = RegisterServer({"holding": self.image, "input": self.image},
                                     host=host, port=port, unit_id=settings.unit_id)
        for i in range(len(loops)):
            self.refresh(i)
        store.subscribe(self.refresh)

    @property
    def port(self) -> int:
        return self.server.port

    def refresh(self, i: int) -> None:
        a = int(self.addresses[i])
        self.image[a:a + RESULT_BLOCK_SIZE] = result_block(
            self.store.results[i], code=self.store.verdict_code(i),
            word_order=self.settings.word_order)

    async def start(self) -> None:
        await self.server.start()

    async def stop(self) -> None:
        await self.server.stop()
