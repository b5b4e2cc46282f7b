"""Gateway config validation: defaults, examples, big configs, the CLI. (Exact messages
for bad files, every problem at once: the golden cases, tests/cases/*/expected.err.)"""

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
from plcsim import assign_result_blocks

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


def test_result_unit_id_defaults_to_the_server_unit_id() -> None:
    c = parse_config(cfg(), "gw.yaml")
    assert [lp.result_unit_id for lp in c.loops] == [1, 1]
    c = parse_config(cfg(modbus_server={"unit_id": 7}), "gw.yaml")
    assert [lp.result_unit_id for lp in c.loops] == [7, 7]
    data = cfg(modbus_server={"unit_id": 7})
    data["loops"][1]["result_unit_id"] = 2
    assert [lp.result_unit_id for lp in parse_config(data).loops] == [7, 2]


def test_result_blocks_overlap_only_within_a_unit_id() -> None:
    """(The overlaps themselves: tests/cases/overlap-within-a-unit-id.)"""
    data = cfg()
    data["loops"][1]["result_address"] = 0  # same address as FIC101 ...
    data["loops"][1]["result_unit_id"] = 2  # ... on another unit id: fine
    c = parse_config(data)
    assert [(lp.result_unit_id, lp.result_address) for lp in c.loops] == [(1, 0), (2, 0)]
    data["loops"][0]["result_unit_id"] = 1  # explicit default: same as leaving it out
    assert parse_config(data).loops == c.loops


def test_ten_thousand_loops_over_four_unit_ids() -> None:
    data = cfg()
    template = data["loops"][0]
    loops = [{**template, "name": f"L{i:05d}",
              "op": {"address": 4 * i, "type": "float32"},
              "pv": {"address": 4 * i + 2, "type": "float32"}}
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


def test_a_file_that_cannot_be_read(tmp_path: Path) -> None:
    """(Empty, broken and empty-list files: tests/cases/empty-file, broken-yaml,
    empty-lists.)"""
    with pytest.raises(ConfigError, match=r"nope.yaml: cannot read: "):
        load_config(tmp_path / "nope.yaml")


@pytest.mark.parametrize("name", ["example.yaml", "plc-sim-gateway.yaml"])
def test_example_gateway_configs_load(name: str) -> None:
    c = load_config(CONFIGS / name)
    assert c.loops
    assert c.devices


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


def test_site_and_area_are_label_values() -> None:
    """gateway.site / gateway.area become label values (docs/fleet.md): letters, digits,
    '_', '.', '-', at most 64, no spaces; both optional."""
    ok = parse_config(cfg(gateway={"site": "plant-north_2", "area": "U3.crude"}), "gw.yaml")
    assert (ok.gateway.site, ok.gateway.area) == ("plant-north_2", "U3.crude")
    assert parse_config(cfg(gateway={"area": "U3"}), "gw.yaml").gateway.site is None
    rule = "must be 1-64 letters, digits, '_', '.' or '-', starting with a letter or digit"
    assert problems(cfg(gateway={"site": "plant north", "area": 7})) == [
        f"gw.yaml: gateway: key 'site': {rule}, was 'plant north'",
        f"gw.yaml: gateway: key 'area': {rule}, was 7",
    ]
    assert problems(cfg(gateway={"site": "-x"}))[0].endswith("was '-x'")
    assert problems(cfg(gateway={"site": "x" * 65}))
    assert problems(cfg(gateway={"site": ""}))
