"""The simulated PLC's config, and the gateway config it writes."""

from __future__ import annotations

import io
import types
from pathlib import Path

import numpy as np
import pytest

from gateway.config import load_config, parse_config
from gateway.core.plantview import PlantGroup, PlantView
from gateway.core.store import ResultStore
from gateway.errors import ConfigError
from plcsim import gateway_config as sim_gateway_config
from plcsim import load_sim_config, parse_sim_config
from plcsim.demo import render_table
from plcsim.sim import PlcSim

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


def test_a_plant_scenario_is_served_after_the_loops_and_read_by_its_gateway_config() -> None:
    """Issue 21: ``plants:`` adds a NAMED_PLANTS plant (its loops prefixed, 4 registers
    each, after the single loops); the gateway config reads them with their process."""
    cfg = parse_sim_config({"listen": "127.0.0.1:0", "seed": 3,
                            "loops": [{"name": "FIC101", "scenario": "healthy"}],
                            "plants": [{"plant": "sticky-feeds-two", "prefix": "U2.",
                                        "duration_s": 600}]})
    assert cfg.loop_names() == ["FIC101", "U2.FIC101", "U2.TIC201", "U2.LIC301",
                                "U2.PIC401", "U2.FIC102"]
    gw = sim_gateway_config(cfg)
    lic = next(lp for lp in gw["loops"] if lp["name"] == "U2.LIC301")
    assert lic["op"] == {"address": 12, "type": "float32"}
    assert lic["process"] == "integrating" and lic["result_address"] == 60
    # the plant's loops are one plant unit (issue 29): the plant view keeps them apart from
    # the single loops beside them, whatever their periods
    assert {lp["name"]: lp.get("unit") for lp in gw["loops"]} == {
        "FIC101": None, **{f"U2.{n}": "U2" for n in ("FIC101", "TIC201", "LIC301", "PIC401",
                                                     "FIC102")}}
    named = parse_sim_config({"plants": [{"plant": "two-sources", "unit": "area 7"}]})
    assert {lp.get("unit") for lp in sim_gateway_config(named)["loops"]} == {"area 7"}
    sim = PlcSim(cfg)
    first = sim.op[1:].copy()
    for _ in range(600):  # the precomputed 600 s, then replayed from the start
        sim.step()
    assert np.array_equal(sim.op[1:], first) and not np.array_equal(sim.pv[1:], sim.pv[:1])
    with pytest.raises(ConfigError, match=r"loop name 'U2\.FIC101' is taken"):
        parse_sim_config({"loops": [{"name": "U2.FIC101", "scenario": "healthy"}],
                          "plants": [{"plant": "sticky-feeds-two", "prefix": "U2."}]})


def test_the_demo_table_names_each_group_its_source_and_each_loops_role() -> None:
    st = ResultStore(["FIC101", "U2.FIC101", "U2.TIC201"])
    st.set_plant(PlantView((PlantGroup(1, 179.0, "U2.FIC101", ("U2.FIC101", "U2.TIC201")),),
                           {"U2.FIC101": (1, "source"), "U2.TIC201": (1, "follower")}))
    gw = types.SimpleNamespace(store=st, config=types.SimpleNamespace(
        gateway=types.SimpleNamespace(time_scale=40.0)))
    out = io.StringIO()
    render_table(gw, 0.0, out)  # type: ignore[arg-type]
    text = out.getvalue()
    assert "plant group 1: a 179 s cycle, source U2.FIC101, loops U2.FIC101, U2.TIC201" in text
    assert "group 1 source" in text and "group 1 follower" in text
