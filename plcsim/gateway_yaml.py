"""The gateway config (a YAML-ready dict) that reads every loop of a simulated PLC:
``stiction-gateway plc-sim --write-gateway-config``, the demo and the tests use it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import yaml

from gateway.wire.results import RESULT_BLOCK_SIZE, RESULT_LOOPS_PER_UNIT
from stiction.scenarios import Scenario

from .config import REGISTERS_PER_LOOP, SimConfig, SimLoop

__all__ = ["MAX_RESULT_ADDRESS", "assign_result_blocks", "dump_yaml", "gateway_config"]


MAX_RESULT_ADDRESS = (RESULT_LOOPS_PER_UNIT - 1) * RESULT_BLOCK_SIZE
"""The last block start that :func:`gateway_config` fills on one unit id (65,500)."""


def assign_result_blocks(loops: Sequence[dict[str, Any]], unit_id: int = 1) -> None:
    """Give gateway-config loop dicts consecutive result blocks, as :func:`gateway_config`
    does: 3,276 per unit id from ``unit_id`` on (``result_unit_id`` written only where it is
    not ``unit_id``, i.e. not ``modbus_server.unit_id``). Replaces any they had."""
    for i, lp in enumerate(loops):
        unit, k = divmod(i, RESULT_LOOPS_PER_UNIT)
        lp["result_address"] = k * RESULT_BLOCK_SIZE
        lp.pop("result_unit_id", None)
        if unit:
            lp["result_unit_id"] = unit_id + unit


def gateway_config(cfg: SimConfig, *, port: int | None = None, host: str | None = None,
                   analysis_interval_s: float = 300.0, metrics_listen: str = "127.0.0.1:9108",
                   result_listen: str = "127.0.0.1:5020", result_unit_id: int = 1,
                   opcua_security: dict[str, Any] | None = None) -> dict[str, Any]:
    """The gateway config (as a YAML-ready dict) that reads every loop of ``cfg``.

    Result blocks follow each other from address 0 on ``modbus_server.unit_id``
    (``result_unit_id``); when a unit id's register space is full (3,276 loops) they go on
    from address 0 of the next unit id, written as the loop's ``result_unit_id``. A loop
    with its own ``result_address`` keeps it, on the unit id being filled.

    With ``protocol: opcua`` the device is an OPC UA one; its ``security`` section is
    ``opcua_security`` if given, else (for a secured plc-sim) one with the plc-sim's policy,
    mode, certificate and login, and the usual client paths (pki/client.der, pki/client.pem,
    pki/trusted/) to be created with ``stiction-gateway opcua-cert``."""
    loops: list[dict[str, Any]] = []
    unit, next_result = result_unit_id, 0
    for k, lp in enumerate([*cfg.loops, *_plant_loops(cfg)]):
        sc = lp.scenario
        # the valve's position, where the simulated PLC has it (single loops)
        position = ({} if k >= len(cfg.loops) else {"position": (
            {"address": cfg.position_address(k), "type": "float32"}
            if cfg.protocol == "modbus" else {"node": f"ns=2;s={lp.name}.POS"})})
        if lp.result_address is not None:  # on the current unit id
            result_address = lp.result_address
        else:
            if next_result > MAX_RESULT_ADDRESS:  # this unit id is full: the next one
                unit, next_result = unit + 1, 0
            result_address = next_result
        next_result = result_address + RESULT_BLOCK_SIZE
        loops.append({
            "name": lp.name, "device": "plc-sim",
            "op": ({"address": lp.address, "type": "float32"} if cfg.protocol == "modbus"
                   else {"node": f"ns=2;s={lp.name}.OP"}),
            "pv": ({"address": lp.address + 2, "type": "float32"} if cfg.protocol == "modbus"
                   else {"node": f"ns=2;s={lp.name}.PV"}),
            **position,
            "process": "integrating" if sc.integrating else "self-regulating",
            "kp": sc.kp, "delay_s": sc.theta,
            "window_s": lp.window_s if lp.window_s is not None else 3600.0,
            "result_address": result_address,
            **({"result_unit_id": unit} if unit != result_unit_id else {}),
            **({"unit": lp.unit} if lp.unit else {}),
        })
    sim_host, sim_port = cfg.listen
    out = {
        "gateway": {"analysis_interval_s": analysis_interval_s,
                    "time_scale": cfg.time_scale},
        "metrics": {"listen": metrics_listen},
        "modbus_server": {"listen": result_listen, "unit_id": result_unit_id,
                          "word_order": "big"},
        "devices": [{
            "name": "plc-sim", "protocol": "modbus",
            "host": host or sim_host, "port": port if port is not None else sim_port,
            "unit_id": cfg.unit_id or 1, "poll_interval_s": cfg.ts,
            "timeout_s": 1.0, "max_registers_per_request": 125,
            "word_order": cfg.word_order,
        }],
        "loops": loops,
    }
    if cfg.protocol == "opcua":
        device: dict[str, Any] = {
            "name": "plc-sim", "protocol": "opcua",
            "endpoint": f"opc.tcp://{host or sim_host}:{port if port is not None else sim_port}",
            "poll_interval_s": cfg.ts, "timeout_s": 1.0,
        }
        sec = cfg.opcua
        if opcua_security is not None:
            device["security"] = opcua_security
        elif sec is not None:
            policy, mode = sec.policies[0]
            device["security"] = {
                "policy": policy, "mode": mode, "certificate": "pki/client.der",
                "private_key": "pki/client.pem", "server_certificate": str(sec.certificate),
                "trust_store": "pki/trusted/"}
            if sec.users:
                device["security"]["username"] = next(iter(sec.users))
                device["security"]["password_file"] = "secrets/opcua.pw"
        out["devices"] = [device]
    return out


def _plant_loops(cfg: SimConfig) -> list[SimLoop]:
    """The plants' loops as simulated loops (for their points, process and tuning)."""
    out = []
    for p in cfg.plants:
        for k, lp in enumerate(p.loops):
            sc = Scenario(p.name(lp), f"loop of plant {p.scenario.name}", kc=lp.kc, ti=lp.ti,
                          kp=lp.kp, tau=lp.tau, theta=lp.theta, integrating=lp.integrating)
            out.append(SimLoop(p.name(lp), sc, window_s=p.window_s,
                               address=p.address + REGISTERS_PER_LOOP * k, unit=p.unit))
    return out


def dump_yaml(data: dict[str, Any]) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)
