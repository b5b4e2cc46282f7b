"""Stick-slip episodes (stiction without a limit cycle): synthetic windows with known answers,
and the plant-data regression (per-tag balanced accuracy must not fall back)."""

from __future__ import annotations

import numpy as np
import pytest

from stiction import Verdict, analyze
from stiction.detectors.stickslip import stick_slip
from stiction.scenarios import scenario, simulate

RNG = np.random.default_rng(11)
N = 750


def _lag(x: np.ndarray, tau: float) -> np.ndarray:
    y = np.empty_like(x)
    y[0] = x[0]
    c = np.exp(-1.0 / tau)
    for i in range(1, x.size):
        y[i] = c * y[i - 1] + (1 - c) * x[i]
    return y


def _episode(op_kick: float = -0.1, second_gain: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """OP flat, then ramps +2 over 200 samples with PV stuck; PV jumps +2 at 300 (the
    valve breaks away); OP kicks ``op_kick`` there and ramps back down. A second slip the
    other way at 600 with apparent gain sign ``second_gain``."""
    t = np.arange(N)
    op = 50.0 + np.interp(t, [0, 100, 300, 600, N], [0, 0, 2.0, 0.5, 0.5])
    op[300:] += op_kick
    vp = np.where(t < 300, 0.0, 2.0)
    vp[600:] -= 1.5 * second_gain
    pv = 10.0 + _lag(vp, 1.5) + RNG.normal(0, 0.05, N)
    return op + RNG.normal(0, 0.01, N), pv


def test_stick_slip_episode_is_found() -> None:
    op, pv = _episode()
    ss = stick_slip(op, pv)
    assert ss.detected
    first = ss.episodes[0]
    assert abs(first.at - 300) <= 3
    assert first.jump == pytest.approx(2.0, abs=0.5)  # the 5-sample means see the lag
    assert first.op_travel > 1.5
    a = analyze(op, pv, ts=10.0)
    assert a.verdict == Verdict.STICTION, a
    assert {e.test: e.vote for e in a.evidence}["stick_slip"] == 1
    # what the tests saw, then what weighed most (issue 32: never a weight read as a vote)
    assert "Tests: stiction: kano, stick_slip;" in a.reason
    assert "Weighed most in the decision: for stiction: " in a.reason
    # no limit cycle to size from: one episode's OP travel is not the band
    assert a.fd_op is None
    assert "not sized, no limit cycle to read the jumps from" in a.reason


def test_jump_with_an_op_step_is_a_response_not_a_slip() -> None:
    # the same PV jump, but OP steps up with it (a set-point change's proportional kick)
    op, pv = _episode(op_kick=+2.5)
    ss = stick_slip(op, pv)
    assert all(abs(e.at - 300) > 10 for e in ss.episodes)
    assert len(ss.episodes) == 1  # the genuine slip at 600 is still seen


def test_two_gain_signs_are_not_one_valve() -> None:
    op, pv = _episode(second_gain=-1.0)
    ss = stick_slip(op, pv)
    assert len(ss.episodes) == 2
    assert not ss.consistent
    assert not ss.detected


def test_pv_following_op_is_not_stick_slip() -> None:
    # a healthy fast loop: PV follows OP through a short lag, OP ramps and steps
    t = np.arange(N)
    op = 50 + np.interp(t, [0, 100, 300, 301, 600, N], [0, 0, 2, 4, 3, 3])
    pv = 10 + _lag(op - 50, 2.0) + RNG.normal(0, 0.05, N)
    assert not stick_slip(op, pv).detected


def _slow_slip(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Plant record 2411FIC20102_1008_1552 in outline (one noise draw per seed)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N)
    op = 50.0 + np.interp(t, [0, 670, 700, N], [1.4, 0.0, 2.0, 2.0])
    pv = 99.0 + np.interp(t, [0, 702, 705, 712, 715, N], [0, 0, 1.6, 1.6, 2.3, 2.3])
    return op + rng.normal(0, 0.02, N), pv + rng.normal(0, 0.25, N)


def test_slow_slip_after_an_op_reversal_is_found() -> None:
    """Plant record 2411FIC20102_1008_1552 in outline: OP drifts down for most of the window
    (PV on setpoint), turns and ramps up 2 % over 30 samples with PV still, then PV climbs
    2.3 in two stages over 10 samples while OP stays put. The force was built since OP's turn
    (not over the whole still stretch, where OP went both ways), and the slip is wider than
    five samples: found on the 10-sample scale. PV's noise (0.25) is a third of the first
    stage's rise, so some draws hide it: found in at least 3 of 4 of 20 draws (16 today;
    the test once used a generator shared with the file's other tests, so it passed only in
    file order)."""
    found = 0
    for seed in range(20):
        ss = stick_slip(*_slow_slip(seed))
        if ss.detected and len(ss.episodes) == 1:
            (e,) = ss.episodes
            found += 700 <= e.at <= 715 and e.op_travel == pytest.approx(2.0, abs=0.3)
    assert found >= 15
    # one episode is a hint, not a vote: a load step can do the same once
    op, pv = _slow_slip(0)
    a = analyze(op, pv, ts=10.0)
    ev = next(x for x in a.evidence if x.test == "stick_slip")
    assert ev.vote == 0
    assert ev.note.startswith("one stick-slip episode")
    assert a.verdict != Verdict.STICTION


def test_pv_still_and_op_still_is_not_stick_slip() -> None:
    op = 50 + RNG.normal(0, 0.01, N)
    pv = 10 + np.where(np.arange(N) < 400, 0.0, 2.0) + RNG.normal(0, 0.05, N)
    # a PV step with OP not having moved before it: a load step, no stuck phase
    assert not stick_slip(op, pv).detected


@pytest.mark.parametrize(("load_tau", "seed", "start"),
                         [(600.0, 2, 180), (30.0, 2, 180), (30.0, 1, 360)])
def test_pv_wandering_under_a_random_load_is_not_stuck(load_tau: float, seed: int,
                                                       start: int) -> None:
    """A healthy loop under a random load (SD 2 % of span), sampled every 10 s: PV wanders
    inside the stuck band while OP drifts, then swings fast. That is not a stuck valve: the
    spread of PV over the 'stuck' phase is about half the swing (these windows were false
    stick-slip alarms; 4 of the 10 such windows of bench/accuracy/false_alarms.py still are)."""
    res = simulate(scenario("healthy", load_sd=0.02, load_tau=load_tau), duration=7200.0,
                   noise=0.02, seed=seed)
    op, pv = res.op[::10][start : start + 360], res.pv[::10][start : start + 360]
    assert not stick_slip(op, pv).detected
    assert analyze(op, pv, ts=10.0).verdict != Verdict.STICTION
