"""The optional ``position:`` point of a loop: same syntax as op/pv for Modbus and OPC UA,
a ``position`` column in tag lists, checked like the others (check-config names a bad one);
configs without it load as before."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from gateway.config import load_config, parse_config
from gateway.core.windows import loop_signature
from gateway.errors import ConfigError
from gateway.inputs.modbus.config import ModbusPoint
from gateway.runtime.reload import device_points

BASE = """\
devices:
  - {name: plc1, protocol: modbus, host: 10.0.0.1}
  - {name: dcs1, protocol: opcua, endpoint: "opc.tcp://10.0.0.3:4840"}
"""
YAML_LOOPS = BASE + """
loops:
  - {name: FIC101, device: plc1, op: {address: 0, type: float32}, pv: {address: 2, type: float32},
     position: {address: 4, type: int16, scale: 0.01}}
  - {name: TIC205, device: dcs1, op: {node: "ns=2;s=TIC205.OP"}, pv: {node: "ns=2;s=TIC205.PV"},
     position: {node: "ns=2;s=TIC205.POS"}}
  - {name: FIC102, device: plc1, op: {address: 10, type: float32}, pv: {address: 12, type: float32}}
"""


def test_position_in_yaml_for_modbus_and_opcua() -> None:
    c = parse_config(yaml.safe_load(YAML_LOOPS), "gw.yaml")
    fic, tic, plain = c.loops
    assert fic.position is not None
    assert isinstance(fic.position.address, ModbusPoint)
    assert fic.position.address.address == 4
    assert fic.position.scale == 0.01
    assert tic.position is not None
    assert "TIC205.POS" in str(tic.position.address)
    assert plain.position is None
    roles = [(p.loop, p.role) for p in device_points(c.loops_of("plc1"))]
    assert roles == [("FIC101", "op"), ("FIC101", "pv"), ("FIC101", "position"),
                     ("FIC102", "op"), ("FIC102", "pv")]


def test_the_position_column_of_a_tag_list(tmp_path: Path) -> None:
    (tmp_path / "tags.csv").write_text(
        "name,device,op,pv,position,type,position_type,position_scale\n"
        "FIC101,plc1,0,2,4,float32,int16,0.01\n"
        "TIC205,dcs1,ns=2;s=TIC205.OP,ns=2;s=TIC205.PV,ns=2;s=TIC205.POS,,,\n"
        "FIC102,plc1,10,12,,float32,,\n", encoding="utf-8")
    (tmp_path / "gw.yaml").write_text(BASE + "loops_csv: tags.csv\n", encoding="utf-8")
    from_csv = load_config(tmp_path / "gw.yaml")
    from_yaml = parse_config(yaml.safe_load(YAML_LOOPS), "gw.yaml")
    assert from_csv.loops == from_yaml.loops


@pytest.mark.parametrize(("position", "message"), [
    ("{address: 4, type: flaot32}", "key 'position.type': must be one of"),
    ("{address: 2, type: float32}", "pv's registers"),  # overlaps its own PV
    ("{address: 4}", "position.type"),
    ("7", "position"),
])
def test_a_bad_position_is_named(tmp_path: Path, position: str, message: str) -> None:
    path = tmp_path / "gw.yaml"
    path.write_text(BASE + "loops:\n  - {name: FIC101, device: plc1, op: {address: 0, type: "
                    f"float32}}, pv: {{address: 2, type: float32}}, position: {position}}}\n",
                    encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert any("FIC101" in p and message in p for p in err.value.problems), err.value.problems
    if "flaot32" not in position:  # check-config itself: once
        return
    out = subprocess.run([sys.executable, "-m", "gateway.cli", "check-config", str(path)],
                         capture_output=True, text=True, check=False)
    assert out.returncode != 0
    assert message in out.stdout + out.stderr


def test_a_loop_without_a_position_keeps_its_signature() -> None:
    """The signature (what the state file matches windows by) of a loop without a position
    is what it was before the key existed; one with a position differs."""
    c = parse_config(yaml.safe_load(YAML_LOOPS), "gw.yaml")
    plain = c.loops[2]
    assert "position" not in repr(plain)
    assert loop_signature(c, plain).count("PointConfig") == 2
    assert loop_signature(c, c.loops[0]).count("PointConfig") == 3
