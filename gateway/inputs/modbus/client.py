"""Modbus TCP input: one ``AsyncModbusTcpClient`` per device, coalesced reads, numpy decode.

Per poll the adapter sends the fewest read requests the register layout allows: the points'
register spans are merged per table into ranges (spans at most ``merge_gap`` registers apart
join, the gap is read and ignored) and each range is cut into requests of at most
``max_registers_per_request`` registers. A point may straddle two requests; the responses
land in one flat register image and every point is decoded from it.

Decoding is vectorised: points are grouped by (type, word order, byte order) once, at
construction, and each group is decoded per poll with a fancy-index gather and one
``ndarray.view``: no per-point Python work. Word order ``big`` means the most significant
register comes first (the Modbus convention, "ABCD"); byte order ``little`` means the two
bytes inside each register are swapped ("BADC", or "DCBA" with little word order).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from ...config import schema as s
from ...config.schema import MISSING, Section
from ...errors import DeviceError
from ..base import PointSpec, Quality, ReadResult

if TYPE_CHECKING:
    from ...config import DeviceConfig

__all__ = [
    "TYPES",
    "ModbusDeviceOptions",
    "ModbusInput",
    "ModbusPoint",
    "ReadRequest",
    "create_input",
    "decode_registers",
    "encode_values",
    "parse_device",
    "parse_point",
    "plan_requests",
]

log = logging.getLogger("gateway.inputs.modbus")

# type -> (registers, numpy big-endian dtype)
TYPES: dict[str, tuple[int, str]] = {
    "int16": (1, ">i2"), "uint16": (1, ">u2"),
    "int32": (2, ">i4"), "uint32": (2, ">u4"),
    "float32": (2, ">f4"), "float64": (4, ">f8"),
}
TABLES = ("holding", "input")
ORDERS = ("big", "little")
MAX_REGISTERS = 125  # Modbus limit for function codes 3 and 4


@dataclasses.dataclass(frozen=True)
class ModbusDeviceOptions:
    host: str
    port: int
    unit_id: int
    max_registers_per_request: int = MAX_REGISTERS
    word_order: str = "big"
    byte_order: str = "big"
    merge_gap: int = 4  # unused registers read to join two nearly contiguous ranges


@dataclasses.dataclass(frozen=True)
class ModbusPoint:
    address: int
    type: str
    table: str = "holding"
    word_order: str = "big"
    byte_order: str = "big"

    @property
    def width(self) -> int:
        return TYPES[self.type][0]


# ------------------------------------------------------------------------ config plugin


def parse_device(sec: Section) -> ModbusDeviceOptions | Any:
    host = sec.req("host", s.string)
    port = sec.req("port", s.integer(1, 65535))
    unit_id = sec.req("unit_id", s.integer(0, 255))
    max_regs = sec.req("max_registers_per_request", s.integer(1, MAX_REGISTERS))
    word = sec.opt("word_order", s.choice(ORDERS), "big")
    byte = sec.opt("byte_order", s.choice(ORDERS), "big")
    gap = sec.opt("merge_gap", s.integer(0, MAX_REGISTERS), 4)
    values = (host, port, unit_id, max_regs, word, byte, gap)
    if MISSING in values:
        return MISSING
    return ModbusDeviceOptions(*values)


def parse_point(sec: Section, options: ModbusDeviceOptions | None) -> ModbusPoint | Any:
    """A point's Modbus keys; ``options`` None (invalid device) checks them with defaults."""
    options = options or ModbusDeviceOptions("", 502, 1)
    address = sec.req("address", s.integer(0, 65535))
    typ = sec.req("type", s.choice(tuple(TYPES)))
    table = sec.opt("table", s.choice(TABLES), "holding")
    word = sec.opt("word_order", s.choice(ORDERS), options.word_order)
    byte = sec.opt("byte_order", s.choice(ORDERS), options.byte_order)
    if MISSING in (address, typ, table, word, byte):
        return MISSING
    if address + TYPES[typ][0] > 65536:
        sec.error("address", f"{typ} at {address} runs past register 65535")
        return MISSING
    return ModbusPoint(address, typ, table, word, byte)


def create_input(device: DeviceConfig, points: Sequence[PointSpec],
                 **_: Any) -> ModbusInput:
    return ModbusInput(device.name, device.options, points, timeout_s=device.timeout_s)


# ------------------------------------------------------------------------ planning


@dataclasses.dataclass(frozen=True)
class ReadRequest:
    table: str
    address: int
    count: int
    offset: int  # where the answer lands in the flat register image


def plan_requests(points: Sequence[ModbusPoint], max_registers: int = MAX_REGISTERS,
                  merge_gap: int = 0) -> tuple[list[ReadRequest], NDArray[np.intp]]:
    """The read requests for ``points`` and each point's first register in the image.

    Per table the registers used are merged into ranges (gaps up to ``merge_gap`` joined);
    each range of R registers costs ceil(R / max_registers) requests, the minimum."""
    requests: list[ReadRequest] = []
    first = np.zeros(len(points), dtype=np.intp)
    offset = 0
    for table in TABLES:
        idx = [i for i, p in enumerate(points) if p.table == table]
        if not idx:
            continue
        spans = sorted((points[i].address, points[i].address + points[i].width) for i in idx)
        ranges: list[list[int]] = []
        for lo, hi in spans:
            if ranges and lo <= ranges[-1][1] + merge_gap:
                ranges[-1][1] = max(ranges[-1][1], hi)
            else:
                ranges.append([lo, hi])
        range_offset: list[tuple[int, int, int]] = []
        for lo, hi in ranges:
            range_offset.append((lo, hi, offset))
            for start in range(lo, hi, max_registers):
                count = min(max_registers, hi - start)
                requests.append(ReadRequest(table, start, count, offset + start - lo))
            offset += hi - lo
        starts = np.array([r[0] for r in range_offset])
        for i in idx:
            k = int(np.searchsorted(starts, points[i].address, side="right")) - 1
            lo, _hi, off = range_offset[k]
            first[i] = off + points[i].address - lo
    return requests, first


# ------------------------------------------------------------------------ decoding


def decode_registers(regs: NDArray[np.uint16], typ: str, word_order: str = "big",
                     byte_order: str = "big") -> NDArray[np.float64]:
    """Decode a (k, width) array of registers into k values (float64)."""
    width, dtype = TYPES[typ]
    regs = np.asarray(regs, dtype=np.uint16).reshape(-1, width)
    if word_order == "little":
        regs = regs[:, ::-1]
    raw = regs.astype(">u2" if byte_order == "big" else "<u2")  # bytes in MSB-first order
    with np.errstate(invalid="ignore"):  # a signalling NaN from the PLC is just a bad value
        return np.ascontiguousarray(raw).view(dtype).reshape(-1).astype(np.float64)


def encode_values(values: Any, typ: str, word_order: str = "big",
                  byte_order: str = "big") -> NDArray[np.uint16]:
    """Inverse of :func:`decode_registers`: k values → (k, width) registers (uint16)."""
    width, dtype = TYPES[typ]
    vals = np.asarray(values, dtype=np.float64).reshape(-1)
    if dtype[1] in "iu":
        vals = np.round(vals)
    raw = vals.astype(dtype).view(">u2" if byte_order == "big" else "<u2").reshape(-1, width)
    regs = raw.astype(np.uint16)
    return regs[:, ::-1].copy() if word_order == "little" else regs


@dataclasses.dataclass(frozen=True)
class _Group:
    points: NDArray[np.intp]  # indices into the point list
    gather: NDArray[np.intp]  # (k, width) indices into the register image
    typ: str
    word_order: str
    byte_order: str


# ------------------------------------------------------------------------ adapter


class ModbusInput:
    """The :class:`~gateway.inputs.base.DeviceInput` of one Modbus TCP device."""

    def __init__(self, name: str, options: ModbusDeviceOptions, points: Sequence[PointSpec],
                 *, timeout_s: float = 1.0) -> None:
        self.name = name
        self.options = options
        self.points = list(points)
        addrs: list[ModbusPoint] = [p.address for p in self.points]
        self.requests, first = plan_requests(addrs, options.max_registers_per_request,
                                             options.merge_gap)
        self.image_size = sum(r.count for r in self.requests)
        groups: dict[tuple[str, str, str], list[int]] = {}
        for i, a in enumerate(addrs):
            groups.setdefault((a.type, a.word_order, a.byte_order), []).append(i)
        self._groups = []
        for (typ, word, byte), members in groups.items():
            idx = np.array(members, dtype=np.intp)
            gather = first[idx][:, None] + np.arange(TYPES[typ][0])
            self._groups.append(_Group(idx, gather, typ, word, byte))
        self._scale = np.array([p.scale for p in self.points], dtype=np.float64)
        self._offset = np.array([p.offset for p in self.points], dtype=np.float64)
        self._client = AsyncModbusTcpClient(options.host, port=options.port, timeout=timeout_s,
                                            retries=0, reconnect_delay=0)

    @property
    def connected(self) -> bool:
        return bool(self._client.connected)

    async def connect(self) -> None:
        try:
            ok = await self._client.connect()
        except (OSError, ModbusException) as exc:
            raise DeviceError(self.name, "connect", f"cannot connect: {exc}") from exc
        if not ok:
            o = self.options
            raise DeviceError(self.name, "connect", f"cannot connect to {o.host}:{o.port}")

    async def read(self) -> ReadResult:
        t0 = time.time()
        image = np.zeros(self.image_size, dtype=np.uint16)
        failed = np.zeros(self.image_size, dtype=bool)
        errors: list[DeviceError] = []
        unit = self.options.unit_id
        for req in self.requests:
            call = (self._client.read_holding_registers if req.table == "holding"
                    else self._client.read_input_registers)
            try:
                rsp = await call(req.address, count=req.count, device_id=unit)
            except ConnectionException as exc:
                raise DeviceError(self.name, "connect", f"not connected: {exc}") from exc
            except (TimeoutError, ModbusIOException) as exc:
                raise DeviceError(self.name, "timeout", f"no answer: {exc}") from exc
            except (ModbusException, ValueError, OSError) as exc:
                raise DeviceError(self.name, "protocol", str(exc)) from exc
            sl = slice(req.offset, req.offset + req.count)
            if rsp.isError():
                code = getattr(rsp, "exception_code", None)
                errors.append(DeviceError(
                    self.name, "exception",
                    f"{req.table} {req.address}+{req.count}: exception code {code}"))
                failed[sl] = True
                continue
            regs = rsp.registers
            if len(regs) != req.count:
                errors.append(DeviceError(
                    self.name, "protocol",
                    f"{req.table} {req.address}+{req.count}: got {len(regs)} registers"))
                failed[sl] = True
                continue
            image[sl] = regs
        return self._decode(t0, image, failed, tuple(errors))

    def _decode(self, t0: float, image: NDArray[np.uint16], failed: NDArray[np.bool_],
                errors: tuple[DeviceError, ...]) -> ReadResult:
        n = len(self.points)
        values = np.empty(n, dtype=np.float64)
        quality = np.full(n, Quality.GOOD, dtype=np.uint8)
        for g in self._groups:
            values[g.points] = decode_registers(image[g.gather], g.typ, g.word_order,
                                                g.byte_order)
            if errors:
                quality[g.points[failed[g.gather].any(axis=1)]] = Quality.NO_COMM
        with np.errstate(invalid="ignore", over="ignore"):
            values = values * self._scale + self._offset
        bad = ~np.isfinite(values)
        quality[bad & (quality == Quality.GOOD)] = Quality.BAD
        values[quality != Quality.GOOD] = np.nan
        return ReadResult(t0, values, quality, len(self.requests), errors)

    async def close(self) -> None:
        try:
            self._client.close()
        except Exception:  # close never raises, whatever pymodbus does
            log.debug("closing %s", self.name, exc_info=True)
