"""The simulated PLC's step-test mode (issue 30): one loop held in manual plays the step
test; the recording it writes is what `stiction valve-test` reads, and what that reports
is the simulated valve (the whole path: simulated PLC -> recording -> valve-test)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gateway.errors import ConfigError
from plcsim.config import parse_sim_config
from plcsim.sim import PlcSim
from stiction.cli import main
from stiction.valvetest import step_test_levels


def _config(tmp_path: Path, **step_test: object) -> dict:  # type: ignore[type-arg]
    return {"listen": "127.0.0.1:0", "ts": 1.0, "loops": [
        {"name": "FV101", "scenario": "table4-case1", "noise": 0.02,
         "params": {"fs": 0.03, "fd": 0.01, "k": 1.0}},
        {"name": "TIC301", "scenario": "healthy", "noise": 0.02}],
        "step_test": {"loop": "FV101", **step_test}}


def test_the_step_test_recorded_by_the_plc_is_the_valve(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "rec.csv"
    cfg = parse_sim_config(_config(tmp_path, start_s=50, hold_s=30, record=str(record)))
    sim = PlcSim(cfg)
    test = sim.step_test
    assert test is not None
    while not test[2].done:
        sim.step()
    held = sim.op[0]
    for _ in range(20):
        sim.step()
    assert sim.op[0] == held  # after the test the PLC holds the loop in manual
    assert sim.op[1] != pytest.approx(sim.op[0])  # the other loop stays in automatic
    head = record.read_text().splitlines()
    assert head[0] == "t,op,pv,position" and head[1].startswith("50,")
    assert len(head) == 1 + 30 * step_test_levels().size
    for source in ("--pv", "--position"):
        assert main(["valve-test", str(record), "--op-range", "0", "100", "--json", source,
                     source.removeprefix("--")]) == 0
        got = json.loads(capsys.readouterr().out)
        assert got["deadband"] == pytest.approx(4.0, abs=0.4)  # fs + fd
        assert got["resolution"] == pytest.approx(2.0, abs=0.2)  # fs - fd


def test_step_test_section_is_validated(tmp_path: Path) -> None:
    bad = _config(tmp_path, hold_s=2)
    bad["step_test"]["loop"] = "FV999"
    with pytest.raises(ConfigError) as info:
        parse_sim_config(bad, "sim.yaml")
    assert info.value.problems == [
        "sim.yaml: step_test: key 'loop': no single loop 'FV999' (loops: FV101, TIC301)"]
    with pytest.raises(ConfigError) as info:
        parse_sim_config(_config(tmp_path, hold_s=2, speed=1), "sim.yaml")
    assert "sim.yaml: step_test: unknown key 'speed'" in info.value.problems
    assert any("hold_s" in p and "5 samples" in p for p in info.value.problems)
