"""stiction.ranking.suspicion: the score, its tiers and the order, on literal loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stiction.ranking import Suspect, amplitude_weight, rank, suspicion, swing, verdict_order


def test_the_amplitude_weight_is_the_root_of_the_amplitude_in_percent_clipped() -> None:
    assert amplitude_weight(1.0) == 1.0
    assert amplitude_weight(4.0) == 2.0
    assert amplitude_weight(100.0) == 4.0  # clipped at 16 %
    assert amplitude_weight(0.01) == 0.25  # and at 1/16 %
    assert amplitude_weight(None) == amplitude_weight(math.nan) == 1.0  # not known


def test_the_score_is_confidence_times_cost_times_priority() -> None:
    assert suspicion(Suspect("a", "stiction", 0.9, 4.0, 3.0)) == (0, pytest.approx(5.4), 6.0)
    assert suspicion(Suspect("a", "undetermined", 0.5)) == (0, 0.5, 1.0)
    # a valve that does not respond is checked first: scored as certain
    assert suspicion(Suspect("a", "valve_not_responding", None, 50.0, 2.0)) == (0, 2.0, 2.0)
    assert suspicion(Suspect("a", "propagated", 0.95)) == (1, 0.95, 1.0)
    for verdict in ("not_oscillating", "bad_data", "warming_up", "none", "stale"):
        assert suspicion(Suspect("a", verdict, 0.95))[:2] == (2, 0.0)
    # a priority that is no weight counts as 1; a confidence that is none, 0
    assert suspicion(Suspect("a", "stiction", 0.9, None, -1.0))[1] == pytest.approx(0.9)
    assert suspicion(Suspect("a", "undetermined", None))[1] == 0.0


def test_the_list_is_worst_first_with_followers_after_and_the_rest_last() -> None:
    loops = [
        Suspect("calm", "not_oscillating", 0.1),
        Suspect("follower", "propagated", 0.99),
        Suspect("mild", "stiction", 0.9, 0.25),    # a small cycle: 0.9 x 0.5
        Suspect("costly", "undetermined", 0.8, 9.0),  # 0.8 x 3
        Suspect("tuning", "no_stiction", 0.2),
        Suspect("bad", "bad_data"),
        Suspect("sticky", "stiction", 0.95),
    ]
    got = rank(loops)
    assert [r.name for r in got] == ["costly", "sticky", "mild", "tuning", "follower",
                                     "calm", "bad"]
    assert [r.rank for r in got] == list(range(1, 8))
    assert [r.tier for r in got] == [0, 0, 0, 0, 1, 2, 2]
    assert got[0].score == pytest.approx(2.4) and got[-1].score == 0.0


def test_ties_keep_the_order_given() -> None:
    loops = [Suspect(f"L{k}", "stiction", 0.9) for k in range(5)]
    assert [r.name for r in rank(loops)] == [f"L{k}" for k in range(5)]


def test_the_verdicts_own_order_is_by_verdict_then_as_given() -> None:
    loops = [Suspect("u1", "undetermined", 0.99), Suspect("s1", "stiction", 0.88),
             Suspect("n1", "no_stiction", 0.4), Suspect("v1", "valve_not_responding"),
             Suspect("s2", "stiction", 0.99), Suspect("x", "bad_data")]
    assert verdict_order(loops) == ["s1", "s2", "v1", "u1", "n1", "x"]


def test_swing_is_half_the_2_to_98_percent_range_and_ignores_spikes() -> None:
    t = np.arange(2000)
    pv = 50 + 3 * np.sin(2 * np.pi * t / 200)
    pv[::400] = 1e6  # five spikes
    pv[7] = np.nan
    assert swing(pv) == pytest.approx(3.0, abs=0.05)
    assert swing([np.nan, 1.0]) is None
