"""Input adapters, one module per protocol behind the small :class:`DeviceInput` interface.

A protocol is a plugin module ``gateway.inputs.<name>`` (registered in :data:`PROTOCOLS`)
that defines four module-level functions:

``parse_device(section) -> options``
    Read the protocol's own device keys from a :class:`gateway._schema.Section` (the core
    has read ``name``, ``protocol``, ``poll_interval_s``, ``timeout_s``); return a frozen
    dataclass, or ``MISSING`` after recording problems with ``section.error``.
``parse_point(section, options) -> address``
    Read a point's own keys (the core has read ``scale`` and ``offset``); return the
    protocol's point address object (frozen, hashable), or ``MISSING``.
``create_input(device, points, *, time_scale=1.0) -> DeviceInput``
    Build the adapter for one :class:`gateway.config.DeviceConfig` and its ordered
    :class:`PointSpec` list (``PointSpec.address`` is what ``parse_point`` returned).

Plugins are imported lazily, so a protocol's library is only imported when a config uses it.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from .base import DeviceInput, PointSpec, Quality, ReadResult

__all__ = ["PLUGIN_FUNCTIONS", "PROTOCOLS", "DeviceInput", "PointSpec", "Quality", "ReadResult",
           "protocol_names", "protocol_plugin"]

PLUGIN_FUNCTIONS = ("parse_device", "parse_point", "create_input")

PROTOCOLS: dict[str, str] = {
    "modbus": "gateway.inputs.modbus",
    "opcua": "gateway.inputs.opcua",
}


def protocol_names() -> list[str]:
    return [name for name in PROTOCOLS if protocol_plugin(name) is not None]


def protocol_plugin(name: str) -> ModuleType | None:
    """The plugin module of protocol ``name``; None if unknown or not (yet) installed."""
    module = PROTOCOLS.get(name)
    if module is None:
        return None
    try:
        plugin = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            return None
        raise
    if not all(hasattr(plugin, fn) for fn in PLUGIN_FUNCTIONS):
        return None  # an adapter module not (yet) wired up as a plugin
    return plugin
