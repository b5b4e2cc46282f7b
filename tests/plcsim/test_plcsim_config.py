"""The simulated PLC's config, and the gateway config it writes."""

from __future__ import annotations

from pathlib import Path

from gateway.config import load_config, parse_config
from plcsim import gateway_config as sim_gateway_config
from plcsim import load_sim_config, parse_sim_config

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def test_plc_sim_gateway_config_spills_to_further_unit_ids() -> None:
    sim = parse_sim_config({"listen": "127.0.0.1:5502", "loops": [
        {"name": f"L{i}", "scenario": "healthy", "noise": 0.05} for i in range(3277)]})
    data = sim_gateway_config(sim)
    assert data["modbus_server"]["unit_id"] == 1
    assert "result_unit_id" not in data["loops"][3275]
    assert data["loops"][3275]["result_address"] == 65500
    assert (data["loops"][3276]["result_unit_id"], data["loops"][3276]["result_address"]) \
        == (2, 0)
    c = parse_config(data)
    assert {lp.result_unit_id for lp in c.loops} == {1, 2}
    small = sim_gateway_config(load_sim_config(CONFIGS / "plc-sim.yaml"))
    assert not any("result_unit_id" in lp for lp in small["loops"])


def test_example_plc_sim_config_loads_and_matches_its_gateway_config() -> None:
    sim = load_sim_config(CONFIGS / "plc-sim.yaml")
    gw = load_config(CONFIGS / "plc-sim-gateway.yaml")
    assert [lp.name for lp in sim.loops] == [lp.name for lp in gw.loops]
    assert [lp.address for lp in sim.loops] == [lp.op.address.address for lp in gw.loops]
