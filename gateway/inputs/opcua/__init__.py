"""OPC UA input plugin (``protocol: opcua``): config keys, sessions, the client.

``config`` reads the device and point keys (and checks certificate files at load),
``session`` opens secured sessions, ``client`` is the :class:`~gateway.inputs.base.Source`,
``values`` turns DataValues into samples, ``errors`` maps asyncua's exceptions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ...core.points import PointSpec
from .client import OpcUaInput
from .config import (
    POINT_ADDRESS_KEY,
    OpcUaDeviceConfig,
    OpcUaPoint,
    OpcUaSecurity,
    parse_device,
    parse_node_id,
    parse_point,
)

if TYPE_CHECKING:
    from ...config import DeviceConfig

__all__ = ["POINT_ADDRESS_KEY", "OpcUaDeviceConfig", "OpcUaInput", "OpcUaPoint",
           "OpcUaSecurity", "create_input", "parse_device", "parse_node_id", "parse_point"]


def create_input(device: DeviceConfig, points: Sequence[PointSpec], **_: Any) -> OpcUaInput:
    """The source for one configured device."""
    options: OpcUaDeviceConfig = device.options
    cfg = dataclasses.replace(options, name=device.name, poll_interval_s=device.poll_interval_s,
                              timeout_s=device.timeout_s)
    return OpcUaInput(cfg, points)
