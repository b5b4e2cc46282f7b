"""The simulated PLC's step-test mode (issue 30; issue 38 item 13: one an operator would
allow): one loop held in manual at its operating point, left to settle, then a few steps
of 0.5-2 % of span each way around it; the recording it writes is what `stiction
valve-test` reads, and what that reports is the simulated valve (the whole path:
simulated PLC -> recording -> valve-test)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from gateway.errors import ConfigError
from plcsim.config import parse_sim_config
from plcsim.sim import PlcSim
from stiction.cli import main

HOLD_S = 50.0  # FV101's process: tau 12 s, no dead time -> 4 tau, in whole 10 s
SETTLE = 2 * HOLD_S  # manual at the operating point before the first step


def _config(tmp_path: Path, **step_test: object) -> dict:  # type: ignore[type-arg]
    return {"listen": "127.0.0.1:0", "ts": 1.0, "loops": [
        {"name": "FV101", "scenario": "table4-case1", "noise": 0.02,
         "params": {"fs": 0.03, "fd": 0.01, "k": 1.0}},
        {"name": "TIC301", "scenario": "healthy", "noise": 0.02}],
        "step_test": {"loop": "FV101", **step_test}}


def _play(tmp_path: Path, **step_test: object) -> tuple[PlcSim, float, np.ndarray]:
    """The PLC run through its test: the OP automatic left (the step before the test) and
    the recording's columns (t, op, pv, position)."""
    cfg = parse_sim_config(_config(tmp_path, **step_test))
    sim = PlcSim(cfg)
    test = sim.step_test
    assert test is not None
    before = float(sim.op[0])
    while not test[2].done:
        if sim.steps <= cfg.step_test.start_s:  # type: ignore[union-attr]
            before = float(sim.op[0])
        sim.step()
    with (tmp_path / "rec.csv").open() as fh:
        rows = np.array([[float(x) for x in r] for r in list(csv.reader(fh))[1:]])
    return sim, before, rows


@pytest.mark.parametrize("start_s", [0, 600])
def test_the_plc_plays_a_test_an_operator_allows(tmp_path: Path, start_s: int) -> None:
    """Manual at the OP automatic left (no bump; at t = 0 the loop's operating point), PV
    left to settle for two holds, then 24 steps of 0.5, 1 and 2 % each way, never more than
    4 % from there, back to it at the end; holds as long as the process needs (tau 12 s:
    50 s). 5c94178: a 25 % bump at the start, 197 steps over 3 h 17 min, OP down to 0 %."""
    sim, before, rows = _play(tmp_path, start_s=start_s, record=str(tmp_path / "rec.csv"))
    op = rows[:, 1]
    assert rows[0, 0] == start_s and op[0] == pytest.approx(before, abs=1e-4)
    if start_s == 0:
        assert op[0] == pytest.approx(50.0)  # the operating point, not OP's register's 0
    assert np.ptp(op[: int(SETTLE)]) == 0.0 and op[int(SETTLE)] != op[0]  # settles first
    steps = np.diff(op)[np.diff(op) != 0]
    assert steps.size == 24
    assert set(np.round(np.abs(steps), 4)) == {0.5, 1.0, 2.0}
    assert np.abs(op - op[0]).max() <= 4.0 + 1e-4 and op[-1] == pytest.approx(op[0])
    assert rows.shape[0] == SETTLE + 24 * HOLD_S  # 21 min 40 s
    for _ in range(20):
        sim.step()
    assert sim.op[0] == pytest.approx(op[-1])  # after the test the loop stays in manual
    assert sim.op[1] != pytest.approx(sim.op[0])  # the other loop stays in automatic


def test_the_step_test_recorded_by_the_plc_is_the_valve(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Dead band fs + fd = 4 %, resolution fs - fd = 2 %: read within a step (the test's
    steps are 0.5-2 %), the same from PV as from the valve's position."""
    _play(tmp_path, start_s=600, record=str(tmp_path / "rec.csv"))
    got = {}
    for source in ("--pv", "--position"):
        assert main(["valve-test", str(tmp_path / "rec.csv"), "--op-range", "0", "100",
                     "--json", source, source.removeprefix("--")]) == 0
        got[source] = r = json.loads(capsys.readouterr().out)
        assert r["deadband_bounds"][0] <= 4.0 <= r["deadband_bounds"][1]
        assert r["deadband"] == pytest.approx(4.0, abs=1.0)
        assert r["resolution_bounds"][0] <= 2.0 <= r["resolution_bounds"][1]
        assert r["resolution"] == pytest.approx(2.0, abs=1.0)
    assert got["--pv"]["deadband"] == pytest.approx(got["--position"]["deadband"], abs=0.3)


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


def test_default_hold_follows_the_process() -> None:
    """Dead time plus four time constants, at least 30 s, in whole 10 s: a slow
    temperature loop holds long, a level (integrating) short."""
    from plcsim.steptest import default_hold_s  # noqa: PLC0415

    assert default_hold_s(12.0, 0.0, False, 1.0) == HOLD_S
    assert default_hold_s(120.0, 6.0, False, 1.0) == 490.0
    assert default_hold_s(2.0, 0.0, False, 1.0) == 30.0
    assert default_hold_s(1.0, 1.0, True, 1.0) == 30.0
    assert default_hold_s(12.0, 0.0, False, 10.0) == 50.0
