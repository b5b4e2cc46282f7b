"""Issue 30 acceptance: simulated step tests (He, Choudhury and Kano valves, friction from
none to 10 % of span, PV noise, self-regulating processes with and without dead time and
an integrating one, the response read from PV and from the valve's position): the dead
band and the resolution within 10 % of what the simulated valve does (or 0.2 % of span,
whichever is larger); a good valve's test shows no dead band beyond noise. The truth is
the valve model's own (stiction.scenarios.steptest), never read from the recording.
``python -m bench valve_test`` sweeps many more cases."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest

from stiction import ChoudhuryValve, HeValve, KanoValve
from stiction.scenarios.steptest import StepTestRun, simulate_step_test
from stiction.valvetest import analyze_step_test, step_test_levels

LEVELS = step_test_levels()
FLOW = {"kp": 1.0, "tau": 4.0, "theta": 0.0}, 30
DEAD_TIME = {"kp": 2.0, "tau": 10.0, "theta": 5.0}, 60
INTEGRATING = {"kp": 0.2, "theta": 2.0, "integrating": True}, 30
CASES = {
    "he-deadtime": (HeValve(0.03, 0.01, 1.0), DEAD_TIME),  # dead band 4 %, resolution 2 %
    "he-10pct-integrating": (HeValve(0.1, 0.05, 1.0), INTEGRATING),  # the largest friction
    "he-k1.99-flow": (HeValve(0.03, 0.027, 1.99), FLOW),  # the paper's overshoot factor
    "choudhury-20pct-flow": (ChoudhuryValve(0.2, 0.1), FLOW),  # no large step moves it back
    "kano-integrating": (KanoValve(0.02, 0.01), INTEGRATING),
    "choudhury-small-deadtime": (ChoudhuryValve(0.005, 0.0025), DEAD_TIME),  # < 1 %
}


@functools.cache
def _run(case: str) -> StepTestRun:
    valve, (kw, hold) = CASES[case]
    return simulate_step_test(valve, LEVELS, hold=hold, noise_sd=0.05,
                              position_noise_sd=0.02, seed=3, **kw)


def _within(got: float | None, truth: float) -> bool:
    return got is not None and abs(got - truth) <= max(0.1 * truth, 0.2)


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("source", ["pv", "position"])
def test_dead_band_and_resolution_within_ten_percent(case: str, source: str) -> None:
    run = _run(case)
    kw = CASES[case][1][0]
    y = run.pv[0] if source == "pv" else run.vp[0]
    got = analyze_step_test(run.op[0], y, 1.0, source=source, op_range=(0.0, 100.0))
    truth_db, truth_res = float(run.deadband[0]), float(run.resolution[0])
    assert truth_db > 0.4 and truth_res > 0.2  # a sticky valve, moved both ways
    assert _within(got.deadband, truth_db), (got.deadband, truth_db)
    assert _within(got.resolution, truth_res), (got.resolution, truth_res)
    assert got.unit == "% of span"
    assert got.process == ("valve position" if source == "position"
                           else "integrating" if kw.get("integrating") else "self-regulating")


@pytest.mark.parametrize("process", [FLOW, DEAD_TIME, INTEGRATING], ids=["flow", "deadtime",
                                                                       "integrating"])
def test_a_good_valve_shows_no_dead_band_beyond_noise(process: Any) -> None:
    kw, hold = process
    run = simulate_step_test(HeValve(0.0, 0.0, 1.0), LEVELS, hold=hold, noise_sd=0.1, seed=5,
                             **kw)
    got = analyze_step_test(run.op[0], run.pv[0], 1.0, op_range=(0.0, 100.0))
    assert got.deadband == 0.0 and got.resolution == 0.0 and got.slip == 0.0
    assert got.deadband_bounds[1] <= 0.2 + 1e-9  # below the smallest step
    moved = [s.moved for s in got.steps]
    assert all(moved), f"{moved.count(False)} steps not followed"
    gains = np.array([s.gain for s in got.steps])
    assert np.median(gains) == pytest.approx(1.0, abs=0.05)


def test_response_times_of_a_first_order_process() -> None:
    """T63 = dead time + lag and T86 = dead time + 2 lags for a first-order lag after a
    dead time (ISA-75.25.01's T86 includes the dead time); a good valve, so every step's
    response is the process's."""
    levels = [50.0, 52.0, 54.0, 52.0, 50.0, 55.0, 60.0, 55.0, 50.0, 60.0, 70.0, 60.0, 50.0]
    run = simulate_step_test(HeValve(0.0, 0.0, 1.0), levels, hold=90, kp=2.0, tau=20.0,
                             theta=10.0, noise_sd=0.02, seed=1)
    got = analyze_step_test(run.op[0], run.pv[0], 1.0)
    big = got.steps
    assert len(big) == 12
    # sample k's PV is computed before the valve moves at k: one sample more of dead time
    t63 = np.median([s.t63_s for s in big])
    t86 = np.median([s.t86_s for s in big])
    dead = np.median([s.dead_time_s for s in big])
    assert t63 == pytest.approx(11.0 + 20.0, abs=1.5)
    assert t86 == pytest.approx(11.0 + 2 * 20.0, abs=2.0)
    assert 10.0 <= dead <= 13.0
    assert max(s.overshoot for s in big) <= 0.02
    assert got.gain == pytest.approx(2.0, rel=0.02)
