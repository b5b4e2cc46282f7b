"""The simulated PLC and the demo, shipped beside the gateway but not part of the daemon.

:class:`~plcsim.sim.PlcSim` serves OP/PV registers (Modbus TCP, or OPC UA through
:class:`~plcsim.opcua.OpcUaPlcServer`) driven sample by sample by stiction's closed-loop
simulator; :mod:`plcsim.config` reads its YAML config; :func:`~plcsim.gateway_config.gateway_config`
writes the gateway config that reads it; :mod:`plcsim.demo` runs both with a live table.
Only the CLI commands ``plc-sim`` and ``demo`` load this package.
"""

from .config import SimConfig, SimLoop, load_sim_config, parse_sim_config
from .gateway_config import assign_result_blocks, dump_yaml, gateway_config
from .opcua import NAMESPACE_URI, OpcUaPlcServer, ServerSecurity
from .sim import PlcSim, serve

__all__ = ["NAMESPACE_URI", "OpcUaPlcServer", "PlcSim", "ServerSecurity", "SimConfig",
           "SimLoop", "assign_result_blocks", "dump_yaml", "gateway_config", "load_sim_config",
           "parse_sim_config", "serve"]
