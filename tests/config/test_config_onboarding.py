"""Issue 16, config side: defaults for the obvious keys, result addresses assigned by the
documented rule (docs/configuration.md#result-addresses), and every existing config loading
as it did before (a snapshot taken with the code before the change)."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gateway.config import load_config, parse_config
from gateway.config.addresses import describe_assigned
from gateway.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).resolve().parent / "golden" / "existing-configs.txt"
CLI = [sys.executable, "-m", "gateway.cli"]


def loop(name: str, device: str = "plc1", **extra: Any) -> dict[str, Any]:
    at = 4 * (next(_ADDRESSES) % 16000)  # its own registers: check-config refuses overlaps
    return {"name": name, "device": device, "op": {"address": at, "type": "float32"},
            "pv": {"address": at + 2, "type": "float32"}, **extra}


_ADDRESSES = itertools.count()


def cfg(loops: list[dict[str, Any]], **top: Any) -> Any:
    raw = {"devices": [{"name": "plc1", "protocol": "modbus", "host": "10.0.0.1"}],
           "loops": loops, **top}
    return parse_config(raw, "gw.yaml")


def addresses(config: Any) -> list[tuple[str, int, int]]:
    return [(lp.name, lp.result_unit_id, lp.result_address) for lp in config.loops]


# ------------------------------------------------------------------ defaults


def test_the_smallest_config_has_every_default() -> None:
    c = parse_config({
        "devices": [{"name": "plc1", "protocol": "modbus", "host": "10.0.0.1"},
                    {"name": "dcs1", "protocol": "opcua", "endpoint": "opc.tcp://10.0.0.2:4840"}],
        "loops": [loop("FIC101"),
                  {"name": "TIC205", "device": "dcs1", "op": {"node": "ns=2;s=TIC205.OP"},
                   "pv": {"node": "ns=2;s=TIC205.PV"}}]}, "gw.yaml")
    plc, dcs = c.devices
    o = plc.options
    assert (o.host, o.port, o.unit_id, o.max_registers_per_request) == ("10.0.0.1", 502, 1, 125)
    assert (plc.poll_interval_s, plc.timeout_s) == (1.0, 1.0)
    assert (dcs.poll_interval_s, dcs.timeout_s) == (1.0, 1.0)
    assert addresses(c) == [("FIC101", 1, 0), ("TIC205", 1, 20)]
    assert c.assigned == ("FIC101", "TIC205")


@pytest.mark.parametrize(("device", "timeout"), [
    ({"poll_interval_s": 0.25}, 0.25),  # never more than the poll interval
    ({"poll_interval_s": 5}, 1.0),
    ({"poll_interval_s": 0.25, "timeout_s": 0.5}, 0.5),  # an explicit timeout is kept
    ({"protocol": "opcua", "endpoint": "opc.tcp://h:4840", "poll_interval_s": 0.5}, 0.5),
])
def test_default_timeout_is_one_second_at_most_the_poll_interval(device: dict[str, Any],
                                                                 timeout: float) -> None:
    dev = {"name": "plc1", "protocol": "modbus", "host": "h", **device}
    if dev["protocol"] == "opcua":
        dev.pop("host")
    lp = loop("A") if dev["protocol"] == "modbus" else {
        "name": "A", "device": "plc1", "op": {"node": "i=1"}, "pv": {"node": "i=2"}}
    c = parse_config({"devices": [dev], "loops": [lp]}, "gw.yaml")
    assert c.devices[0].timeout_s == timeout


def test_defaulted_keys_are_still_checked() -> None:
    with pytest.raises(ConfigError) as err:
        parse_config({"devices": [{"name": "plc1", "protocol": "modbus", "host": "h",
                                   "port": 0, "poll_interval_s": -1}],
                      "loops": [loop("A")]}, "gw.yaml")
    assert err.value.problems == [
        "gw.yaml: device plc1: key 'poll_interval_s': must be > 0, was -1",
        "gw.yaml: device plc1: key 'port': must be in 1..65535, was 0"]


def test_every_existing_config_loads_as_before() -> None:
    """configs/*.yaml and the golden cases that load: the same devices, loops (with their
    result blocks) and settings as the code before defaults and tag lists."""
    want = GOLDEN.read_text().splitlines()
    got = []
    for line in want:
        path = line.split(": ", 1)[0]
        c = load_config(ROOT / path)
        assert c.assigned == ()
        got.append(f"{path}: {c.devices!r} {c.loops!r} {c.gateway!r} {c.metrics!r} "
                   f"{c.modbus_server!r} {[lp.result_unit_id for lp in c.loops]!r}")
    assert got == want
    assert {line.split(": ", 1)[0] for line in want} >= {
        "configs/example.yaml", "configs/plc-sim-gateway.yaml"}


# ------------------------------------------------------------------ result addresses


def test_assigned_in_config_order_per_unit_id_around_explicit_blocks() -> None:
    c = cfg([loop("A"), loop("B", result_address=20), loop("C"), loop("D", result_unit_id=2),
             loop("E", result_address=45), loop("F"), loop("G", result_unit_id=2),
             loop("H")], modbus_server={"unit_id": 1})
    # E's block 45..64 overlaps the blocks at 40 and 60: neither is free
    assert addresses(c) == [("A", 1, 0), ("B", 1, 20), ("C", 1, 80), ("D", 2, 0),
                            ("E", 1, 45), ("F", 1, 100), ("G", 2, 20), ("H", 1, 120)]
    assert c.assigned == ("A", "C", "D", "F", "G", "H")


def test_an_explicit_address_wins_even_after_the_loops_that_skip_it() -> None:
    c = cfg([loop("A"), loop("B"), loop("C", result_address=0)])
    assert addresses(c) == [("A", 1, 20), ("B", 1, 40), ("C", 1, 0)]


def test_appending_loops_never_moves_an_assigned_block() -> None:
    loops = [loop("L0", result_address=40), loop("L1"), loop("L2", result_unit_id=3)]
    before = addresses(cfg(loops))
    for k in range(3, 30):
        extra = {"result_unit_id": 3} if k % 3 == 0 else {}
        loops.append(loop(f"L{k}", **extra))
        now = addresses(cfg(loops))
        assert now[:len(before)] == before
        before = now
    blocks = sorted((u, a) for _, u, a in before)
    assert len(set(blocks)) == len(blocks)  # never two loops on one block


def test_a_full_unit_id_is_an_error_naming_the_loop() -> None:
    loops = [loop(f"L{k:04d}") for k in range(3277)]
    with pytest.raises(ConfigError) as err:
        cfg(loops)
    assert err.value.problems == [
        "gw.yaml: loop L3276: key 'result_address': no free result block left on result unit "
        "id 1 (3,276 blocks of 20 registers): set result_unit_id (or result_address)"]


def test_check_config_says_what_it_assigned(tmp_path: Path) -> None:
    path = tmp_path / "gw.yaml"
    rows = "\n".join(f"  - {{name: F{k:03d}, device: plc1, op: {{address: {4 * k}, type: "
                     f"float32}}, pv: {{address: {4 * k + 2}, type: float32}}}}"
                     for k in range(10))
    path.write_text("devices: [{name: plc1, protocol: modbus, host: 10.0.0.1}]\nloops:\n"
                    + rows + "\n  - {name: X, device: plc1, op: {address: 40, type: int16}, "
                    "pv: {address: 41, type: int16}, result_address: 0, result_unit_id: 2}\n"
                    "  - {name: Y, device: plc1, op: {address: 42, type: int16}, "
                    "pv: {address: 43, type: int16}, result_unit_id: 2}\n")
    res = subprocess.run([*CLI, "check-config", str(path)], capture_output=True, text=True,
                         timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [
        f"{path}: ok (1 device(s), 12 loop(s))",
        f"{path}: result_address assigned to 11 loop(s) without one (unit id, first of 20 "
        "registers):",
        "  F000 .. F009 (10 loops, in config order): unit id 1, result_address 0, 20, .. 180",
        "  Y: unit id 2, result_address 20"]
    assert describe_assigned(load_config(ROOT / "configs" / "example.yaml")) == []
