"""The Modbus keys of a device and of a point, read with the config's one validator."""

from __future__ import annotations

import dataclasses
from typing import Any

from ...config import schema as s
from ...config.schema import MISSING, Section
from ...wire.codec import TYPES

__all__ = [
    "DEFAULT_PORT",
    "MAX_REGISTERS",
    "POINT_ADDRESS_KEY",
    "ModbusDeviceOptions",
    "ModbusPoint",
    "parse_device",
    "parse_point",
]

POINT_ADDRESS_KEY = "address"
"""The point key a tag list's op/pv cell fills (a register number; gateway.config.tags)."""

TABLES = ("holding", "input")
ORDERS = ("big", "little")
MAX_REGISTERS = 125  # Modbus limit for function codes 3 and 4
DEFAULT_PORT = 502  # Modbus TCP


@dataclasses.dataclass(frozen=True)
class ModbusDeviceOptions:
    host: str
    port: int = DEFAULT_PORT
    unit_id: int = 1
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

    def __str__(self) -> str:
        orders = "" if (self.word_order, self.byte_order) == ("big", "big") else \
            f" {self.word_order}/{self.byte_order}"
        return f"{self.table} {self.address} {self.type}{orders}"


def parse_device(sec: Section) -> ModbusDeviceOptions | Any:
    host = sec.req("host", s.string)
    port = sec.opt("port", s.integer(1, 65535), DEFAULT_PORT)
    unit_id = sec.opt("unit_id", s.integer(0, 255), 1)
    max_regs = sec.opt("max_registers_per_request", s.integer(1, MAX_REGISTERS), MAX_REGISTERS)
    word = sec.opt("word_order", s.choice(ORDERS), "big")
    byte = sec.opt("byte_order", s.choice(ORDERS), "big")
    gap = sec.opt("merge_gap", s.integer(0, MAX_REGISTERS), 4)
    values = (host, port, unit_id, max_regs, word, byte, gap)
    if MISSING in values:
        return MISSING
    return ModbusDeviceOptions(*values)


def parse_point(sec: Section, options: ModbusDeviceOptions | None) -> ModbusPoint | Any:
    """A point's Modbus keys; ``options`` None (invalid device) checks them with defaults."""
    options = options or ModbusDeviceOptions("")
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
