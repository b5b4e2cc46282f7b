"""The plugin registry: a protocol or an output is a module, found here by name.

An input plugin (``protocol: <name>`` in a device) defines ``parse_device``,
``parse_point`` and ``create_input`` (see :mod:`gateway.inputs`); an output plugin defines
``create_sink`` (see :mod:`gateway.outputs`). Adding one is one line in :data:`INPUTS` or
:data:`OUTPUTS`. Modules are imported lazily (by name, not by an import statement), so a
protocol's library is only loaded when a config uses it and the config package never
imports the inputs or the outputs.
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["INPUTS", "INPUT_FUNCTIONS", "OUTPUTS", "OUTPUT_FUNCTIONS", "input_names",
           "input_plugin", "output_plugin"]

INPUTS: dict[str, str] = {
    "modbus": "gateway.inputs.modbus",
    "opcua": "gateway.inputs.opcua",
    "memory": "gateway.inputs.memory",
}
"""Protocol name (a device's ``protocol``) -> input plugin module."""

OUTPUTS: dict[str, str] = {
    "modbus_server": "gateway.outputs.modbus_server",
    "prometheus": "gateway.outputs.prometheus",
    "statefile": "gateway.outputs.statefile",
    "verdicts": "gateway.outputs.verdicts",
    "sitecal": "gateway.outputs.sitecal",
    "memory": "gateway.outputs.memory",
}
"""Output name -> output plugin module."""

INPUT_FUNCTIONS = ("parse_device", "parse_point", "create_input")
OUTPUT_FUNCTIONS = ("create_sink",)


def input_names() -> list[str]:
    """The protocols a config may name (registered and importable)."""
    return [name for name in INPUTS if input_plugin(name) is not None]


def input_plugin(name: str) -> ModuleType | None:
    """The plugin module of protocol ``name``; None if unknown or not (yet) installed."""
    return _plugin(INPUTS, name, INPUT_FUNCTIONS)


def output_plugin(name: str) -> ModuleType | None:
    """The plugin module of output ``name``; None if unknown or not (yet) installed."""
    return _plugin(OUTPUTS, name, OUTPUT_FUNCTIONS)


def _plugin(registry: dict[str, str], name: str, functions: tuple[str, ...]
            ) -> ModuleType | None:
    module = registry.get(name)
    if module is None:
        return None
    try:
        plugin = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            return None
        raise
    if not all(hasattr(plugin, fn) for fn in functions):
        return None  # a module not (yet) wired up as a plugin
    return plugin
