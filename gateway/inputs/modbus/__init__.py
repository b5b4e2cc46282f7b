"""Modbus TCP input plugin (``protocol: modbus``): config keys, request plan, client.

``config`` reads the device and point keys, ``plan`` coalesces the points into the fewest
read requests, ``client`` is the :class:`~gateway.inputs.base.Source`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ...core.points import PointSpec
from .client import ModbusInput
from .config import POINT_ADDRESS_KEY, ModbusDeviceOptions, ModbusPoint, parse_device, parse_point
from .plan import ReadRequest, plan_requests

if TYPE_CHECKING:
    from ...config import DeviceConfig

__all__ = ["POINT_ADDRESS_KEY", "ModbusDeviceOptions", "ModbusInput", "ModbusPoint",
           "ReadRequest", "create_input", "parse_device", "parse_point", "plan_requests",
           "point_span"]


def create_input(device: DeviceConfig, points: Sequence[PointSpec], **_: Any) -> ModbusInput:
    return ModbusInput(device.name, device.options, points, timeout_s=device.timeout_s)


def point_span(address: ModbusPoint) -> tuple[str, int, int]:
    """The registers a point reads: (table, first, end), for the config's overlap check
    (:mod:`gateway.config.overlaps`)."""
    return address.table, address.address, address.address + address.width
