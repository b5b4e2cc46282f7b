"""A read-only Modbus TCP server over numpy register images.

:class:`RegisterServer` answers function codes 3 and 4 (read holding / input registers)
from one uint16 image per table and unit id; updating an image is a numpy assignment. The
gateway's result server (:mod:`gateway.outputs.modbus_server`) and the simulated PLC
(:mod:`plcsim`) both serve through it. It is an asyncio protocol on a
:class:`~gateway.wire.listener.Listener` (connection limit, idle timeout, a few requests per
turn of the event loop, answers not read stop the reading, garbage closes the connection),
and answers as the Modbus application protocol (V1.1b3) says:

* an exception response carries the request's function code | 0x80;
* exception 1 (illegal function): every function but 3, 4 and 43/14 - writes (5, 6, 15,
  16, 22, 23, counted in ``refused_writes``), bit reads, diagnostics (8), report server id
  (17) - and 43/14 (read device identification) when no identification is configured;
* exception 3 (illegal data value): a count outside 1..125 or a request of the wrong length;
* exception 2 (illegal data address): registers beyond the image;
* exception 0x0A (gateway path unavailable): a unit id not served;
* exception 4 (server device failure): an unexpected error while answering (logged).

The MBAP header is checked: a protocol id other than 0 or a length outside 2..254 closes the
connection. Identification (43/14) answers exactly the objects given, nothing else.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .listener import Conn, Listener, ListenerStats

__all__ = ["DEFAULT_IDLE_TIMEOUT_S", "DEFAULT_MAX_CONNECTIONS", "EXC_DEVICE_FAILURE",
           "EXC_GATEWAY_PATH",
           "EXC_ILLEGAL_ADDRESS", "EXC_ILLEGAL_FUNCTION", "EXC_ILLEGAL_VALUE",
           "IDENTIFICATION_OBJECTS", "RegisterServer", "answer_identification"]

READ_CODES = {3: "holding", 4: "input"}
WRITE_CODES = frozenset({5, 6, 15, 16, 22, 23})
MAX_READ = 125
EXC_ILLEGAL_FUNCTION, EXC_ILLEGAL_ADDRESS, EXC_ILLEGAL_VALUE = 1, 2, 3
EXC_GATEWAY_PATH = 0x0A
EXC_DEVICE_FAILURE = 4
DEFAULT_MAX_CONNECTIONS = 64
DEFAULT_IDLE_TIMEOUT_S = 60.0
IDENTIFICATION_OBJECTS = ("vendor_name", "product_code", "revision", "vendor_url",
                          "product_name", "model_name", "application_name")
"""Object ids 0..6 of read device identification (0-2 basic, 3-6 regular)."""
_MBAP = struct.Struct(">HHHB")


def _exception(fc: int, code: int) -> bytes:
    return bytes(((fc | 0x80) & 0xFF, code))


def answer_identification(pdu: bytes, objects: Mapping[int, bytes]) -> bytes:
    """The answer to 43/14 (read device identification) from ``objects`` (object id ->
    value), stream access (codes 1-3) or one object (code 4)."""
    if len(pdu) != 4:
        return _exception(0x2B, EXC_ILLEGAL_VALUE)
    code, first = pdu[2], pdu[3]
    regular = any(k >= 3 for k in objects)
    if code == 4:
        if first not in objects:
            return _exception(0x2B, EXC_ILLEGAL_ADDRESS)
        ids = [first]
    elif code in (1, 2, 3):
        top = 2 if code == 1 else 6
        ids = [k for k in sorted(objects) if k <= top]
        ids = [k for k in ids if k >= first] or ids  # an unknown start restarts at 0
    else:
        return _exception(0x2B, EXC_ILLEGAL_VALUE)
    body = b"".join(bytes((k, len(objects[k]))) + objects[k] for k in ids)
    conformity = 0x82 if regular else 0x81
    return bytes((0x2B, 0x0E, code, conformity, 0, 0, len(ids))) + body


class _ModbusConn(Conn):
    """One client connection: MBAP frames in, answers out, in order, a few per turn."""

    in_limit = 4096  # 15 frames of the longest kind; a pipelining client waits for the rest

    def ready(self) -> bool:
        buf = self.buffer
        if len(buf) < 7:
            return False
        protocol, length = struct.unpack_from(">HH", buf, 2)
        return protocol != 0 or not 2 <= length <= 254 or len(buf) >= 6 + length

    def serve(self, n: int) -> int:
        server: RegisterServer = self.listener.owner
        buf = self.buffer
        out: list[bytes] = []
        while len(out) < n and len(buf) >= 7:
            tid, protocol, length, unit = _MBAP.unpack_from(buf)
            if protocol != 0 or not 2 <= length <= 254:
                self.drop("protocol")
                return len(out) + 1
            end = 6 + length
            if len(buf) < end:
                break
            pdu = bytes(buf[7:end])
            del buf[:end]
            reply = server.respond(unit, pdu)
            out.append(_MBAP.pack(tid, 0, len(reply) + 1, unit) + reply)
        if out:
            self.write(b"".join(out))  # one write (one system call) per turn
            self.served(len(out))
        return len(out)


class RegisterServer:
    """A Modbus TCP server answering reads from uint16 register images, per unit id.

    ``units`` maps each served unit id to its images by table (``{"holding": img,
    "input": img}``; one array may serve both tables); the one-unit form
    ``RegisterServer(images, unit_id=...)`` is ``units={unit_id: images}``. ``self.units``
    may be replaced (or its images swapped) at any time. Unit id 0 is the catch-all: a
    request for a unit id not in ``units`` is answered from unit 0's images if there are
    any, else with exception 0x0A. ``identification`` (object name -> text, see
    :data:`IDENTIFICATION_OBJECTS`) is what 43/14 answers; without it 43 is refused.
    ``requests`` counts the reads answered from an image, ``refused_writes`` the writes;
    ``stats`` (shared by successive servers of one output) the connections."""

    def __init__(self, images: dict[str, NDArray[np.uint16]] | None = None, *, host: str,
                 port: int, unit_id: int = 1, capacity: int | None = None,
                 units: Mapping[int, dict[str, NDArray[np.uint16]]] | None = None,
                 max_connections: int = DEFAULT_MAX_CONNECTIONS,
                 idle_timeout_s: float = DEFAULT_IDLE_TIMEOUT_S,
                 identification: Mapping[str, str] | None = None,
                 stats: ListenerStats | None = None) -> None:
        del capacity  # accepted for compatibility: images may grow up to 65,536 registers
        if units is None:
            if images is None:
                raise TypeError("RegisterServer needs images or units")
            units = {unit_id: images}
        self.units: dict[int, dict[str, NDArray[np.uint16]]] = dict(units)
        self.unit_id = unit_id if images is not None else min(self.units)
        self.requests = 0
        self.refused_writes = 0
        self.identification: dict[int, bytes] = {}
        self.set_identification(identification or {})
        self.listener = Listener("modbus", _ModbusConn, host=host, port=port, owner=self,
                                 max_connections=max_connections,
                                 idle_timeout_s=idle_timeout_s, stats=stats)

    @property
    def images(self) -> dict[str, NDArray[np.uint16]]:
        """The images of the unit id given at construction (the one-unit form)."""
        return self.units[self.unit_id]

    @property
    def port(self) -> int:
        return self.listener.port

    def set_identification(self, identification: Mapping[str, str]) -> None:
        """What 43/14 answers from now on (object name -> text); empty: refused."""
        self.identification = _objects(identification)

    def respond(self, unit: int, pdu: bytes) -> bytes:
        """:meth:`answer`; an unexpected exception answers exception 4 (server device
        failure), counted and logged by cause, and the connection goes on."""
        try:
            return self.answer(unit, pdu)
        except Exception as exc:
            self.listener.failed("request", exc)
            return _exception(pdu[0] if pdu else 0, EXC_DEVICE_FAILURE)

    def answer(self, unit: int, pdu: bytes) -> bytes:
        """The response PDU to request ``pdu`` for ``unit``."""
        fc = pdu[0] if pdu else 0
        images = self.units.get(unit)
        if images is None:
            images = self.units.get(0)
            if images is None:
                return _exception(fc, EXC_GATEWAY_PATH)
        table = READ_CODES.get(fc)
        if table is None:
            if fc in WRITE_CODES:
                self.refused_writes += 1
            elif fc == 0x2B and self.identification and len(pdu) >= 2 and pdu[1] == 0x0E:
                return answer_identification(pdu, self.identification)
            return _exception(fc, EXC_ILLEGAL_FUNCTION)
        if len(pdu) != 5:
            return _exception(fc, EXC_ILLEGAL_VALUE)
        address, count = struct.unpack_from(">HH", pdu, 1)
        if not 1 <= count <= MAX_READ:
            return _exception(fc, EXC_ILLEGAL_VALUE)
        self.requests += 1
        img = images.get(table)
        if img is None or address + count > len(img):
            return _exception(fc, EXC_ILLEGAL_ADDRESS)
        return bytes((fc, 2 * count)) + img[address:address + count].astype(">u2").tobytes()

    async def open(self) -> None:
        """Bind the address without serving yet (OSError if it is in use)."""
        await self.listener.open()

    async def start(self) -> None:
        await self.listener.start()

    async def stop(self) -> None:
        await self.listener.stop()


def _objects(identification: Mapping[str, str]) -> dict[int, bytes]:
    out = {}
    for k, name in enumerate(IDENTIFICATION_OBJECTS):
        text = identification.get(name)
        if text:
            out[k] = text.encode("utf-8")[:240]
    return out
