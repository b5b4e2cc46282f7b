"""The Modbus keys of a device and of a point, read with the config's one validator."""

from __future__ import annotations

import dataclasses
from typing import Any

from ...config import schema as s
from ...config.schema import MISSING, Section
from ...wire.codec import TYPES

__all__ = ["MAX_REGISTERS", "ModbusDeviceOptions", "ModbusPoint", "parse_device",
           "parse_point"]

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
