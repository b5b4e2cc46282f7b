"""Gateway config validation: exact messages, every problem at once, defaults, examples."""

from __future__ import annotations

import collections
import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from gateway.cli import main
from gateway.config import load_config, parse_config
from gateway.errors import ConfigError
from gateway.inputs.modbus import ModbusDeviceOptions, ModbusPoint
from plcsim import assign_result_blocks, load_sim_config, parse_sim_config
from plcsim import gateway_config as sim_gateway_config

CONFIGS = Path(__file__).resolve().parents[2] / "configs"

BASE: dict[str, Any] = {
    "devices": [{
        "name": "plc1", "protocol": "modbus", "host": "127.0.0.1", "port": 502,
        "unit_id": 1, "poll_interval_s": 1.0, "timeout_s": 1.0,
        "max_registers_per_request": 125,
    }],
    "loops": [
        {"name": "FIC101", "device": "plc1",
         "op": {"address": 0, "type": "float32"}, "pv": {"address": 2, "type": "float32"},
         "result_address": 0},
        {"name": "FIC102", "device": "plc1",
         "op": {"address": 4, "type": "float32"}, "pv": {"address": 6, "type": "float32"},
         "result_address": 20},
    ],
}


def problems(data: Any, source: str = "gw.yaml") -> list[str]:
    with pytest.raises(ConfigError) as info:
        parse_config(data, source)
    return info.value.problems


def cfg(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    data.update(changes)
    return data


def test_minimal_config_gets_documented_defaults() -> None:
    c = parse_config(cfg(), "gw.yaml")
    assert c.gateway.analysis_interval_s == 300.0
    assert c.gateway.time_scale == 1.0
    assert c.metrics.listen == ("127.0.0.1", 9108)
    assert c.modbus_server.listen == ("127.0.0.1", 5020)
    assert c.modbus_server.unit_id == 1
    assert c.modbus_server.word_order == "big"
    lp = c.loops[0]
    assert (lp.process, lp.kp, lp.delay_s, lp.window_s, lp.op_range) == (
        "self-regulating", None, 0.0, 7200.0, (0.0, 100.0))
    assert lp.op.address == ModbusPoint(0, "float32", "holding", "big", "big")
    assert (lp.pv.scale, lp.pv.offset) == (1.0, 0.0)
    assert c.devices[0].options == ModbusDeviceOptions("127.0.0.1", 502, 1, 125)
    assert c.window_samples(lp) == 7200


def test_unknown_key_is_an_error() -> None:
    data = cfg()
    data["loops"][0]["windows_s"] = 3600
    assert problems(data) == ["gw.yaml: loop FIC101: unknown key 'windows_s'"]


def test_unknown_nested_and_section_keys() -> None:
    data = cfg(gateway={"analysis_intervall_s": 60})
    data["loops"][1]["pv"]["tabel"] = "input"
    assert problems(data) == [
        "gw.yaml: gateway: unknown key 'analysis_intervall_s'",
        "gw.yaml: loop FIC102: unknown key 'pv.tabel'",
    ]


def test_missing_key() -> None:
    data = cfg()
    del data["devices"][0]["host"]
    del data["loops"][1]["result_address"]
    assert problems(data) == [
        "gw.yaml: device plc1: missing required key 'host'",
        "gw.yaml: loop FIC102: missing required key 'result_address'",
    ]


def test_bad_types() -> None:
    data = cfg(metrics={"listen": 9108})
    data["devices"][0]["port"] = "502"
    data["loops"][0]["kp"] = "fast"
    data["loops"][0]["op"]["type"] = "float"
    assert problems(data) == [
        "gw.yaml: metrics: key 'listen': must be 'host:port', was 9108",
        "gw.yaml: device plc1: key 'port': must be an integer, was '502'",
        "gw.yaml: loop FIC101: key 'op.type': must be one of int16, uint16, int32, uint32, "
        "float32, float64, was 'float'",
        "gw.yaml: loop FIC101: key 'kp': must be a number, was 'fast'",
    ]


def test_overlapping_result_blocks() -> None:
    data = cfg()
    data["loops"][1]["result_address"] = 10
    assert problems(data) == [
        "gw.yaml: loop FIC102: key 'result_address': block 10..29 overlaps loop FIC101 (0..19)",
    ]


def test_result_unit_id_defaults_to_the_server_unit_id() -> None:
    c = parse_config(cfg(), "gw.yaml")
    assert [lp.result_unit_id for lp in c.loops] == [1, 1]
    c = parse_config(cfg(modbus_server={"unit_id": 7}), "gw.yaml")
    assert [lp.result_unit_id for lp in c.loops] == [7, 7]
    data = cfg(modbus_server={"unit_id": 7})
    data["loops"][1]["result_unit_id"] = 2
    assert [lp.result_unit_id for lp in parse_config(data).loops] == [7, 2]


def test_bad_result_unit_id() -> None:
    data = cfg()
    data["loops"][0]["result_unit_id"] = 0
    data["loops"][1]["result_unit_id"] = "two"
    data["loops"].append({**data["loops"][1], "name": "FIC103", "result_unit_id": 248,
                          "result_address": 40})
    assert problems(data) == [
        "gw.yaml: loop FIC101: key 'result_unit_id': must be in 1..247, was 0",
        "gw.yaml: loop FIC102: key 'result_unit_id': must be an integer, was 'two'",
        "gw.yaml: loop FIC103: key 'result_unit_id': must be in 1..247, was 248",
    ]


def test_result_blocks_overlap_only_within_a_unit_id() -> None:
    data = cfg()
    data["loops"][1]["result_address"] = 0  # same address as FIC101 ...
    data["loops"][1]["result_unit_id"] = 2  # ... on another unit id: fine
    c = parse_config(data)
    assert [(lp.result_unit_id, lp.result_address) for lp in c.loops] == [(1, 0), (2, 0)]
    data["loops"][0]["result_unit_id"] = 1  # explicit default: same as leaving it out
    assert parse_config(data).loops == c.loops
    data["loops"].append({**data["loops"][1], "name": "FIC103", "result_address": 10})
    data["loops"].append({**data["loops"][1], "name": "FIC104", "result_address": 5,
                          "result_unit_id": 1})
    assert problems(data) == [
        "gw.yaml: loop FIC104: key 'result_address': block 5..24 overlaps loop FIC101 (0..19)",
        "gw.yaml: loop FIC103: key 'result_address': block 10..29 overlaps loop FIC102 "
        "(0..19) on result unit id 2",
    ]


def test_ten_thousand_loops_over_four_unit_ids() -> None:
    data = cfg()
    template = data["loops"][0]
    loops = [{**template, "name": f"L{i:05d}",
              "op": {"address": 4 * (i % 2000), "type": "float32"},
              "pv": {"address": 4 * (i % 2000) + 2, "type": "float32"}}
             for i in range(10_000)]
    assign_result_blocks(loops, unit_id=1)
    data["loops"] = loops
    c = parse_config(data)
    assert len(c.loops) == 10_000
    per_unit = collections.Counter(lp.result_unit_id for lp in c.loops)
    assert per_unit == {1: 3276, 2: 3276, 3: 3276, 4: 172}
    assert (c.loops[3275].result_unit_id, c.loops[3275].result_address) == (1, 65500)
    assert (c.loops[3276].result_unit_id, c.loops[3276].result_address) == (2, 0)
    assert "result_unit_id" not in loops[0]  # the default unit id is left implicit
    # all on one unit id: refused, every loop past the register space named
    for lp in loops:
        lp.pop("result_unit_id", None)
    got = problems(data)
    assert len(got) == 10_000 - 3276
    assert got[0] == ("gw.yaml: loop L03276: key 'result_address': block 0..19 overlaps "
                      "loop L00000 (0..19)")


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


def test_loop_naming_an_unknown_device() -> None:
    data = cfg()
    data["loops"][1]["device"] = "plc9"
    assert problems(data) == [
        "gw.yaml: loop FIC102: key 'device': unknown device 'plc9' (devices: plc1)",
    ]


def test_every_problem_reported_at_once() -> None:
    data = cfg()
    data["devices"][0]["max_registers_per_request"] = 200
    data["loops"][0]["device"] = "plc2"
    data["loops"][1]["process"] = "integral"
    data["loops"][1]["result_address"] = 5
    got = problems(data)
    assert got == [
        "gw.yaml: device plc1: key 'max_registers_per_request': must be in 1..125, was 200",
        "gw.yaml: loop FIC101: key 'device': unknown device 'plc2' (devices: plc1)",
        "gw.yaml: loop FIC102: key 'process': must be one of self-regulating, integrating, "
        "was 'integral'",
        "gw.yaml: loop FIC102: key 'result_address': block 5..24 overlaps loop FIC101 (0..19)",
    ]


def test_other_checks() -> None:
    data = cfg(modbus_server={"word_order": "middle"})
    data["loops"][1]["name"] = "FIC101"
    data["loops"][1]["result_address"] = 40
    data["loops"][0]["window_s"] = 5
    data["loops"][0]["op_range"] = [100, 0]
    data["devices"].append({"name": "opc", "protocol": "profinet", "poll_interval_s": 1,
                            "timeout_s": 1})
    assert problems(data) == [
        "gw.yaml: modbus_server: key 'word_order': must be one of big, little, was 'middle'",
        "gw.yaml: device opc: key 'protocol': unknown protocol 'profinet' "
        "(known: modbus, opcua, memory)",
        "gw.yaml: loop FIC101: key 'op_range': must be finite with hi > lo, was [100, 0]",
        "gw.yaml: loop FIC101: key 'window_s': must hold at least 16 samples of device plc1 "
        "(poll_interval_s 1)",
        "gw.yaml: loop FIC101: key 'name': duplicate loop name 'FIC101'",
    ]


def test_empty_and_broken_files(tmp_path: Path) -> None:
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ConfigError, match=r"empty.yaml: top level: the file is empty"):
        load_config(empty)
    broken = tmp_path / "broken.yaml"
    broken.write_text("devices: [\n")
    with pytest.raises(ConfigError, match=r"broken.yaml: invalid YAML: "):
        load_config(broken)
    with pytest.raises(ConfigError, match=r"nope.yaml: cannot read: "):
        load_config(tmp_path / "nope.yaml")
    assert problems({"loops": []}) == [
        "gw.yaml: top level: missing required key 'devices'",
        "gw.yaml: top level: key 'loops': must be a non-empty list, was []",
    ]


@pytest.mark.parametrize("name", ["example.yaml", "plc-sim-gateway.yaml"])
def test_example_gateway_configs_load(name: str) -> None:
    c = load_config(CONFIGS / name)
    assert c.loops
    assert c.devices


def test_example_plc_sim_config_loads_and_matches_its_gateway_config() -> None:
    sim = load_sim_config(CONFIGS / "plc-sim.yaml")
    gw = load_config(CONFIGS / "plc-sim-gateway.yaml")
    assert [lp.name for lp in sim.loops] == [lp.name for lp in gw.loops]
    assert [lp.address for lp in sim.loops] == [lp.op.address.address for lp in gw.loops]


def test_every_file_in_configs_is_covered() -> None:
    names = {p.name for p in CONFIGS.glob("*.yaml")}
    assert names <= {"example.yaml", "plc-sim.yaml", "plc-sim-gateway.yaml"}, names


def test_check_config_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check-config", str(CONFIGS / "example.yaml")]) == 0
    assert "ok (2 device(s), 3 loop(s))" in capsys.readouterr().out
    data = cfg()
    data["loops"][0]["colour"] = "red"
    data["loops"][1]["device"] = "plc9"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    assert main(["check-config", str(bad)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"{bad}: loop FIC101: unknown key 'colour'",
        f"{bad}: loop FIC102: key 'device': unknown device 'plc9' (devices: plc1)",
    ]
