"""A read-only Modbus TCP server over numpy register images (pymodbus 3.16 SimDevice API).

:class:`RegisterServer` serves one uint16 image per table through a ``SimDevice`` action
hook: each read copies just the requested slice of the image into pymodbus' registers, so
updating the image is a numpy assignment and never goes through pymodbus. It also counts the
requests it served, which the tests use to prove that the gateway coalesces its reads. The
gateway's result server (:mod:`gateway.outputs.modbus_server`) and the simulated PLC
(:mod:`plcsim`) both serve through it.

It is read-only: every write (function codes 5, 6, 15, 16, 22, 23) and every
coil/discrete-input read is answered with exception 1 (illegal function).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

__all__ = ["RegisterServer"]

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
