"""Step tests in pieces, on literal arrays: what counts as a step (and what is refused as no
step test), and the dead band, resolution and slip read from which steps moved the valve."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stiction import ChoudhuryValve, HeValve, KanoValve, StictionError
from stiction.models.simulate import LoopBank, LoopParams
from stiction.scenarios.steptest import simulate_step_test, travel_to_move
from stiction.valvetest import NotAStepTest, analyze_step_test, hold_series
from stiction.valvetest.bands import bands
from stiction.valvetest.holds import split_holds


def test_holds_and_steps_of_a_clean_sequence() -> None:
    op = hold_series(np.array([50.0, 51.0, 50.5, 52.0]), 10)
    h = split_holds(op)
    assert h.level.tolist() == [50.0, 51.0, 50.5, 52.0]
    assert h.step_at.tolist() == [0, 10, 20, 30]
    assert h.op_steps.tolist() == [1.0, -0.5, 1.5]


def test_a_historian_interpolated_step_and_gaps_are_one_step() -> None:
    op = np.r_[[50.0] * 10, 50.5, [51.0] * 10, [np.nan] * 3, [51.0] * 5, 51.5, 51.9, [52.0] * 8]
    h = split_holds(op)
    assert h.level.tolist() == [50.0, 51.0, 52.0]
    assert h.step_at.tolist() == [0, 10, 29]


def test_constant_op_is_refused_naming_what_a_step_test_needs() -> None:
    with pytest.raises(NotAStepTest, match=r"OP never steps .*in manual.*reversals"):
        split_holds(np.full(500, 42.0))


def test_op_in_automatic_is_refused() -> None:
    bank = LoopBank(1, LoopParams(kc=1.0, ti=10.0, tau=20.0, load_sd=0.02), HeValve(0, 0, 1.0))
    op = np.array([bank.step().op[0] for _ in range(600)])
    with pytest.raises(NotAStepTest, match=r"OP changes in \d+ of 599 samples .*continuously"):
        analyze_step_test(op, op, 1.0)
    assert issubclass(NotAStepTest, StictionError)


def test_loop_bank_manual_holds_op_and_returns_without_a_bump() -> None:
    bank = LoopBank(2, LoopParams(kc=1.0, ti=20.0, tau=10.0), HeValve(0, 0, 1.0))
    for _ in range(50):
        out = bank.step(sp=55.0, manual=[0.6, np.nan])  # loop 0 in manual, loop 1 in auto
    assert out.op[0] == pytest.approx(60.0)
    assert out.op[1] != pytest.approx(60.0)
    auto = bank.step(sp=55.0)  # back to automatic: it starts where manual left it
    assert abs(auto.op[0] - 60.0) < 1.0


@pytest.mark.parametrize(("valve", "back", "onward"), [
    (HeValve(0.03, 0.01, 1.0), 0.04, 0.02),  # fs + fd after a reversal, fs - fd onward
    (ChoudhuryValve(0.04, 0.02), 0.04, 0.02),  # S and J
    (KanoValve(0.04, 0.02), 0.04, 0.02),
])
def test_the_truth_probe_reads_each_model_as_published(valve: object, back: float,
                                                       onward: float) -> None:
    state = valve.initial_state(np.array([0.5]))  # type: ignore[attr-defined]
    for u in (0.52, 0.53, 0.6):  # moving up, to rest
        state = valve.step(state, np.array([u]))  # type: ignore[attr-defined]
    state = valve.step(state, np.array([0.6]))  # type: ignore[attr-defined]
    u = np.array([0.6])
    assert travel_to_move(valve, state, u, np.array([-1.0]))[0] == pytest.approx(back, abs=1e-5)
    assert travel_to_move(valve, state, u, np.array([1.0]))[0] == pytest.approx(onward, abs=1e-5)


def test_bands_bracket_the_first_move_after_a_reversal() -> None:
    # up by 0.5s (the valve moves at 52), down by 0.5s: no move until 49.5 (travel 2.5)
    levels = np.array([50.0, 51.0, 52.0, 51.5, 51.0, 50.5, 50.0, 49.5, 49.0, 48.5, 48.0])
    moved = np.array([False, True, False, False, False, False, True, False, False, True])
    travel = np.array([0, 2.0, 0, 0, 0, 0, -1.0, 0, 0, -1.5])
    b = bands(levels, moved, travel)
    assert (b.deadband.low, b.deadband.high) == (2.0, 2.5)
    # the valve travelled 1.0 of OP's 2.5 back: a width of 1.5, plus the resolution (1.25)
    # is 2.75, kept inside the bracket
    assert b.deadband.value == pytest.approx(2.5)
    assert (b.resolution.low, b.resolution.high) == (1.0, 1.5)  # 49.5 -> 48.5 did not, 48 did
    assert b.slip == pytest.approx(1.5)  # it stuck two steps, then jumped 1.5


def test_lost_motion_reads_the_dead_band_between_coarse_steps() -> None:
    """He's valve with K = 1, fs 3, fd 1 (dead band 4, resolution 2) under 5 % steps: the
    bracket is (0, 5]; the travel after the reversal (3 of 5) tells the lost motion, 2 fd
    = 2, plus the resolution where the steps see one (here they cannot: every 5 % step
    moved it, so it reads 0, below the finest step)."""
    levels = np.array([50.0, 55.0, 60.0, 55.0, 50.0, 45.0])
    moved = np.ones(5, bool)
    travel = np.array([4.0, 5.0, -3.0, -5.0, -5.0])  # x = u - fd going up, u + fd down
    b = bands(levels, moved, travel)
    assert (b.deadband.low, b.deadband.high) == (0.0, 5.0)
    assert b.resolution.value == 0.0 and b.resolution.high == 5.0
    assert b.deadband.value == pytest.approx(2.0)
    # with 1 % steps after the move the stick band shows: 2 + 2 (bracket (1, 2]: 1.5)
    levels = np.array([50.0, 55.0, 60.0, 55.0, 54.0, 53.0, 52.0])
    moved = np.array([True, True, True, False, True, False])
    travel = np.array([4.0, 5.0, -3.0, 0.0, -2.0, 0.0])
    b = bands(levels, moved, travel)
    assert b.resolution.value == pytest.approx(1.5)
    assert b.deadband.value == pytest.approx(2.0 + 1.5)


def test_a_valve_that_follows_every_step_has_no_band_below_the_smallest_step() -> None:
    levels = np.array([50.0, 50.2, 50.4, 50.2, 50.0, 52.0])
    b = bands(levels, np.ones(5, bool), np.diff(levels))
    assert b.deadband.value == 0.0 and b.resolution.value == 0.0 and b.slip == 0.0
    assert b.deadband.high == pytest.approx(0.2)


def test_a_valve_that_never_moves_back_has_no_dead_band_figure() -> None:
    levels = np.array([50.0, 51.0, 52.0, 51.0, 50.0])
    b = bands(levels, np.array([True, True, False, False]), np.array([1.0, 1.0, 0, 0]))
    assert b.deadband.value is None and b.deadband.low == 2.0 and math.isinf(b.deadband.high)


def test_arguments_are_checked_by_name() -> None:
    op = hold_series(np.array([50.0, 51.0]), 10)
    with pytest.raises(ValueError, match="`response` must have as many samples as op"):
        analyze_step_test(op, op[:-1], 1.0)
    with pytest.raises(ValueError, match="`source` must be one of pv, position"):
        analyze_step_test(op, op, 1.0, source="travel")
    with pytest.raises(ValueError, match="`op_range`"):
        analyze_step_test(op, op, 1.0, op_range=(100.0, 0.0))
    run = simulate_step_test(HeValve(0.0, 0.0, 1.0), [50.0, 52.0, 54.0], hold=20)
    assert analyze_step_test(run.op[0], run.pv[0], 1.0).steps[0].moved
