"""Modbus TCP source: one ``AsyncModbusTcpClient`` (one connection) per device.

Per read the source sends the requests :func:`~.plan.plan_requests` planned and decodes
every point from the flat register image, vectorised: points are grouped by (type, word
order, byte order) once, at construction, and each group is decoded per read with a
fancy-index gather and one ``ndarray.view`` (:mod:`gateway.wire.codec`): no per-point Python
work. pymodbus errors are mapped to :class:`~gateway.errors.DeviceError` here; the client
never retries by itself (``retries=0``): the poller owns reconnecting.

A request the PLC refuses (a Modbus exception) leaves its points NO_COMM and is one
:class:`~gateway.errors.DeviceError` of kind ``exception`` in the read's ``errors``, in
words with the fix and the loops (and tag-list lines) it holds (:mod:`.exceptions`); its
``reason`` (``illegal data address``, ``unit id 5 not served``) is what the metrics' labels
say. A read whose every request was refused leaves the poller to call the device down.

Answers are checked strictly, and an answer that is not the one asked for is a protocol
error (kind ``protocol``), never data: another function code than the request's (4 for
3), fewer or more registers than asked, or a frame pymodbus cannot decode (a byte count
beyond the frame); the last fails the request at once (pymodbus would raise it on the event
loop, log a traceback and leave the request to time out) and the connection is closed.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from ...core.points import PointSpec, Quality
from ...errors import DeviceError
from ...wire.codec import TYPES, decode_registers
from ..base import ReadResult
from .config import ModbusDeviceOptions, ModbusPoint
from .exceptions import refusal
from .plan import plan_requests

__all__ = ["ModbusInput"]

log = logging.getLogger("gateway.inputs.modbus")


@dataclasses.dataclass(frozen=True)
class _Group:
    points: NDArray[np.intp]  # indices into the point list
    gather: NDArray[np.intp]  # (k, width) indices into the register image
    typ: str
    word_order: str
    byte_order: str


class ModbusInput:
    """The :class:`~gateway.inputs.base.Source` of one Modbus TCP device."""

    def __init__(self, name: str, options: ModbusDeviceOptions, points: Sequence[PointSpec],
                 *, timeout_s: float = 1.0) -> None:
        self.name = name
        self.options = options
        self.points = list(points)
        addrs: list[ModbusPoint] = [p.address for p in self.points]
        self.requests, first = plan_requests(addrs, options.max_registers_per_request,
                                             options.merge_gap)
        self.image_size = sum(r.count for r in self.requests)
        self._first = first  # each point's first register in the image
        self._width = np.array([a.width for a in addrs], dtype=np.intp)
        self._failed: list[tuple[slice, str]] = []  # failed requests of the last read
        groups: dict[tuple[str, str, str], list[int]] = {}
        for i, a in enumerate(addrs):
            groups.setdefault((a.type, a.word_order, a.byte_order), []).append(i)
        self._groups = []
        for (typ, word, byte), members in groups.items():
            idx = np.array(members, dtype=np.intp)
            gather = first[idx][:, None] + np.arange(TYPES[typ][0])
            self._groups.append(_Group(idx, gather, typ, word, byte))
        self.timeout_s = timeout_s
        self._client = AsyncModbusTcpClient(options.host, port=options.port, timeout=timeout_s,
                                            retries=0, reconnect_delay=0)
        _strict_frames(self._client)

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
        self._failed = []
        for req in self.requests:
            call = (self._client.read_holding_registers if req.table == "holding"
                    else self._client.read_input_registers)
            what = f"{req.table} {req.address}+{req.count}"
            try:
                rsp = await call(req.address, count=req.count, device_id=unit)
            except ConnectionException as exc:
                raise DeviceError(self.name, "connect", f"not connected: {exc}") from exc
            except (TimeoutError, ModbusIOException) as exc:
                raise DeviceError(self.name, "timeout", f"{what} (unit id {unit}): no answer "
                                  f"within {self.timeout_s:g} s: {exc}") from exc
            except (ModbusException, ValueError, OSError) as exc:
                raise DeviceError(self.name, "protocol", f"{what}: {exc}") from exc
            sl = slice(req.offset, req.offset + req.count)
            fc = 3 if req.table == "holding" else 4
            if getattr(rsp, "function_code", fc) & 0x7F != fc:
                errors.append(DeviceError(self.name, "protocol", f"{what}: answered with "
                                          f"function code {rsp.function_code}, not {fc}"))
            elif rsp.isError():
                reason, message = refusal(getattr(rsp, "exception_code", None), req.table,
                                          req.address, req.count, unit=unit,
                                          points=self._points_of(sl))
                errors.append(DeviceError(self.name, "exception", message, reason=reason))
            elif len(rsp.registers) != req.count:
                errors.append(DeviceError(self.name, "protocol",
                                          f"{what}: got {len(rsp.registers)} registers"))
            else:
                image[sl] = rsp.registers
                continue
            failed[sl] = True
            self._failed.append((sl, str(errors[-1]).removeprefix(f"device {self.name}: ")))
        return self._decode(t0, image, failed, tuple(errors))

    def _points_of(self, sl: slice) -> list[PointSpec]:
        """The points with a register in image slice ``sl`` (one request's answer)."""
        hit = (self._first < sl.stop) & (self._first + self._width > sl.start)
        return [self.points[int(i)] for i in np.flatnonzero(hit)]

    def point_status(self) -> list[str]:
        """Per point, the failed request of the last read that holds it ('' if none)."""
        out = [""] * len(self.points)
        for sl, message in self._failed:
            for i in np.flatnonzero((self._first >= sl.start) & (self._first < sl.stop)):
                out[int(i)] = message
        return out

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
        values[quality != Quality.GOOD] = np.nan
        return ReadResult(t0, values, quality, len(self.requests), errors)

    async def close(self) -> None:
        try:
            self._client.close()
        except Exception:  # close never raises, whatever pymodbus does
            log.debug("closing %s", self.name, exc_info=True)


class UndecodableAnswer(ModbusException):
    """The PLC's answer is not a Modbus frame pymodbus can decode."""


def _strict_frames(client: AsyncModbusTcpClient) -> None:
    """Make a frame pymodbus cannot decode fail the waiting request with
    :class:`UndecodableAnswer` (mapped to a protocol error by :meth:`ModbusInput.read`)
    and drop the connection, instead of raising on the event loop (pymodbus 3.16: an
    unlimited traceback per answer, then a timeout)."""
    ctx = getattr(client, "ctx", None)
    decode = getattr(ctx, "callback_data", None)
    if ctx is None or decode is None:
        return

    def callback_data(data: bytes, addr: tuple[Any, ...] | None = None) -> int:
        try:
            return int(decode(data, addr))
        except Exception as exc:
            waiting = getattr(ctx, "response_future", None)
            if waiting is not None and not waiting.done():
                waiting.set_exception(UndecodableAnswer(f"undecodable answer: {exc}"))
            transport = getattr(ctx, "transport", None)
            if transport is not None:
                transport.abort()
            return len(data)

    ctx.callback_data = callback_data
