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
    from .client import OpcUaInput

__all__ = ["POINT_ADDRESS_KEY", "SPAN_WORDS", "OpcUaDeviceConfig", "OpcUaInput", "OpcUaPoint",
           "OpcUaSecurity", "create_input", "parse_device", "parse_node_id", "parse_point",
           "point_span", "span_text"]

SPAN_WORDS = ("is", "node", "node id")
"""How check-config names two points of one node (gateway.config.overlaps)."""


def point_span(address: OpcUaPoint) -> tuple[str, int, int]:
    """The node a point reads, for the config's overlap check (:mod:`gateway.config.overlaps`):
    two points of one device with the same (canonical) node id overlap."""
    return address.node, 0, 1


def span_text(space: str, first: int, end: int) -> str:
    return f"node {space}"


def create_input(device: DeviceConfig, points: Sequence[PointSpec], **_: Any) -> OpcUaInput:
    """The source for one configured device."""
    options: OpcUaDeviceConfig = device.options
    cfg = dataclasses.replace(options, name=device.name, poll_interval_s=device.poll_interval_s,
                              timeout_s=device.timeout_s)
    from .client import OpcUaInput  # noqa: PLC0415  (asyncua: 2-4 s, only when polling)

    return OpcUaInput(cfg, points)


def __getattr__(name: str) -> Any:
    """``OpcUaInput`` on first use (PEP 562): reading or checking a config (check-config, the
    overlap check of every protocol) never imports asyncua."""
    if name == "OpcUaInput":
        from .client import OpcUaInput  # noqa: PLC0415

        return OpcUaInput
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
