"""Inputs: one folder per protocol, each a plugin behind the small :class:`Source` interface.

A protocol is a module ``gateway.inputs.<name>`` registered by one line in
:data:`gateway.config.plugins.INPUTS`, defining three module-level functions:

``parse_device(section) -> options``
    Read the protocol's own device keys from a :class:`gateway.config.schema.Section` (the
    config loader has read ``name``, ``protocol``, ``poll_interval_s``, ``timeout_s``);
    return a frozen dataclass, or ``MISSING`` after recording problems with
    ``section.error``.
``parse_point(section, options) -> address``
    Read a point's own keys (the loader reads ``scale``, ``offset`` and ``range``); return
    the protocol's point address object (frozen, hashable), or ``MISSING``. ``options`` is
    None when the device itself is invalid.
``create_input(device, points, **kwargs) -> Source``
    Build the source for one :class:`gateway.config.DeviceConfig` and its ordered
    :class:`PointSpec` list (``PointSpec.address`` is what ``parse_point`` returned).

``modbus/`` and ``opcua/`` talk to PLCs; ``memory/`` replays literal values (tests, and
trying the outputs without a PLC).
"""

from .base import PointSpec, Quality, ReadResult, Source

__all__ = ["PointSpec", "Quality", "ReadResult", "Source"]
