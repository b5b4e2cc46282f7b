"""The simulated PLC and the demo, shipped beside the gateway but not part of the daemon.

:class:`~plcsim.sim.PlcSim` serves OP/PV registers (Modbus TCP, or OPC UA through
:class:`~plcsim.opcua.OpcUaPlcServer`) driven sample by sample by stiction's closed-loop
simulator; :mod:`plcsim.config` reads its YAML config; :func:`~plcsim.gateway_yaml.gateway_config`
writes the gateway config that reads it; :mod:`plcsim.demo` runs both with a live table.
The commands ``plc-sim`` and ``demo`` (:mod:`plcsim.commands`) join ``stiction-gateway``
through an entry point; the names below load their module on first use, so registering the
commands costs no import of the simulator.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .config import SimConfig, SimLoop, load_sim_config, parse_sim_config
    from .gateway_yaml import assign_result_blocks, dump_yaml, gateway_config
    from .opcua import NAMESPACE_URI, OpcUaPlcServer, ServerSecurity
    from .sim import PlcSim, serve

_WHERE = {
    "SimConfig": ".config", "SimLoop": ".config", "load_sim_config": ".config",
    "parse_sim_config": ".config", "assign_result_blocks": ".gateway_yaml",
    "dump_yaml": ".gateway_yaml", "gateway_config": ".gateway_yaml",
    "NAMESPACE_URI": ".opcua", "OpcUaPlcServer": ".opcua", "ServerSecurity": ".opcua",
    "PlcSim": ".sim", "serve": ".sim",
}

__all__ = ["NAMESPACE_URI", "OpcUaPlcServer", "PlcSim", "ServerSecurity", "SimConfig",
           "SimLoop", "assign_result_blocks", "dump_yaml", "gateway_config", "load_sim_config",
           "parse_sim_config", "serve"]


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name], __name__), name)
    raise AttributeError(f"module 'plcsim' has no attribute {name!r}")
