"""Stuck intervals, PV still while OP ramps (stiction.detectors.kano, Kano et al. 2004)."""

from __future__ import annotations

import numpy as np
import pytest
from detector_fixtures import cached_sim, op_period
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stiction import Evidence, ParameterError
from stiction.detectors.kano import kano_test

STICKY = [
    ("table4-case2", 0.05, 1, {}), ("table4-case2", 0.05, 2, {}),
    ("table4-case2", 0.5, 1, {}), ("table4-case2", 0.5, 2, {}),
    ("table4-case1", 0.05, 1, {"duration": 3600.0}),
    ("table6", 0.05, 1, {"tau": 120.0}), ("table7", 0.2, 1, {"theta": 35.0}),
]


@pytest.mark.parametrize(("name", "noise", "seed", "kw"), STICKY)
def test_sticky_flow_and_slow_loops_say_yes(name: str, noise: float, seed: int,
                                            kw: dict[str, float]) -> None:
    res = cached_sim(name, noise, seed, **kw)
    op, pv = res.op[200:], res.pv[200:]
    k = kano_test(op, pv, period=op_period(op))
    assert k.vote == 1, k
    assert k.index is not None
    assert k.index >= 0.25
    assert k.intervals >= 3
    assert k.band is not None
    assert "stuck" in k.note


def test_band_is_the_op_travel_while_stuck() -> None:
    """Table 4 case 2: OP travels S = 2 fs - J = 54 % between jumps; the stuck intervals
    start once PV has settled after a jump (a few time constants), so they hold a third to
    two thirds of it."""
    res = cached_sim("table4-case2", 0.05, 1)
    op, pv = res.op[200:], res.pv[200:]
    k = kano_test(op, pv, period=op_period(op))
    assert k.band is not None
    assert 54.0 / 3 <= k.band <= 54.0 * 2 / 3


@pytest.mark.parametrize("seed", [1, 2])
def test_integrating_loop_cannot_tell(seed: int) -> None:
    """In a level loop PV ramps while the valve is stuck: PV is no valve proxy, vote 0."""
    res = cached_sim("table5-case2", 0.05, seed)
    op, pv = res.op[800:], res.pv[800:]
    k = kano_test(op, pv, period=op_period(op))
    assert k.vote == 0, k
    assert "no proxy" in k.note


NOT_STICKY = [
    ("healthy", {"load_sd": 0.005, "load_tau": 30.0}),
    ("healthy", {"load_sd": 0.02, "load_tau": 30.0}),
    ("healthy", {"load_sd": 0.005, "load_tau": 600.0}),
    ("healthy", {"load_sd": 0.02, "load_tau": 600.0}),
    ("disturbance", {}),
    ("disturbance", {"load_sd": 0.01, "load_tau": 200.0}),
    ("aggressive-tuning", {}),
    ("aggressive-tuning", {"load_sd": 0.02}),
]


@pytest.mark.parametrize(("name", "kw"), NOT_STICKY)
def test_loops_without_stiction_never_say_yes(name: str, kw: dict[str, float]) -> None:
    """Random loads, a sinusoidal disturbance, aggressive tuning; PV noise 0.05 and 0.2,
    1 s and 10 s sampling, the detected period or none."""
    for noise, seed in ((0.05, 1), (0.2, 2)):
        res = cached_sim(name, noise, seed, duration=4000.0, **kw)
        for step in (1, 10):
            op, pv = res.op[200::step], res.pv[200::step]
            for period in (op_period(op), None):
                k = kano_test(op, pv, period=period)
                assert k.vote != 1, (noise, seed, step, period, k)


@pytest.mark.parametrize("seed", [1, 2])
def test_aggressive_tuning_says_no(seed: int) -> None:
    """PV is still much of the time (between swings of a fast cycle) but never while OP
    ramps: -1."""
    res = cached_sim("aggressive-tuning", 0.05, seed)
    op, pv = res.op[200:], res.pv[200:]
    k = kano_test(op, pv, period=op_period(op))
    assert k.vote == -1, k


def test_linear_valve_that_follows_op_says_no() -> None:
    """OP moves in steps and PV follows each at once (a linear valve on a fast process):
    PV is still most of the time, but only while OP is."""
    rng = np.random.default_rng(3)
    steps = rng.choice([-1.0, 1.0], 40) * rng.uniform(4.0, 8.0, 40)
    op = np.repeat(50.0 + np.cumsum(steps), 60)
    pv = np.convolve(op, np.full(4, 0.25), mode="same") * 2.0 + rng.normal(0.0, 0.05, op.size)
    k = kano_test(op[10:-10], pv[10:-10])
    assert k.vote == -1, k
    assert k.intervals == 0


def test_pv_on_setpoint_while_op_drifts_is_not_stuck() -> None:
    """The known false alarm of this pattern: OP ramps against a slow disturbance while PV
    sits on its setpoint (noise only). PV is still, OP ramps, but PV is not away from its
    centre, so no interval counts."""
    rng = np.random.default_rng(5)
    n = 3600
    op = 40.0 + 10.0 * np.sin(2 * np.pi * np.arange(n) / 3000.0)
    pv = 20.0 + rng.normal(0.0, 0.05, n)
    k = kano_test(op, pv, period=600.0)
    assert k.vote != 1, k
    assert k.intervals == 0


def test_units_do_not_matter() -> None:
    res = cached_sim("table4-case2", 0.05, 1)
    op, pv = res.op[200:], res.pv[200:]
    period = op_period(op)
    a = kano_test(op, pv, period=period)
    b = kano_test(7.0 * op + 300.0, 0.01 * pv - 5.0, period=period)
    c = kano_test(op, -pv, period=period)  # reverse-acting process
    for other in (b, c):
        assert other.vote == a.vote
        assert other.intervals == a.intervals
        for name in ("index", "travel_share", "still_share"):
            assert getattr(other, name) == pytest.approx(getattr(a, name), rel=1e-9, abs=1e-12)
    assert a.band is not None and b.band is not None
    assert b.band == pytest.approx(7.0 * a.band, rel=1e-9)


@pytest.mark.parametrize(("op", "pv", "note"), [
    (np.linspace(0.0, 50.0, 1000), np.zeros(1000), "PV does not move"),
    (np.full(1000, 3.0), np.sin(np.arange(1000.0) / 20), "OP does not move"),
    (np.empty(0), np.empty(0), "too short"),
    (np.arange(10.0), np.arange(10.0), "too short"),
    (np.full(500, np.inf), np.zeros(500), "non-finite"),
    (1e300 * np.sin(np.arange(800.0) / 30), 1e-300 * np.cos(np.arange(800.0) / 30), ""),
])
def test_degenerate_data_votes_zero(op: np.ndarray, pv: np.ndarray, note: str) -> None:
    k = kano_test(op, pv)
    assert k.vote in (-1, 0)
    if note:
        assert k.vote == 0
        assert note in k.note


def test_bad_parameters_name_the_argument() -> None:
    x = np.sin(np.arange(400.0) / 10)
    for bad in (0, -3.0, float("nan"), "ten", True):
        with pytest.raises(ParameterError, match="period"):
            kano_test(x, x, period=bad)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="pv"):
        kano_test(x, x[:-1])
    with pytest.raises(ParameterError, match="pv"):
        kano_test(x.reshape(20, 20), x.reshape(20, 20))


def test_evidence() -> None:
    res = cached_sim("table4-case2", 0.05, 1)
    op, pv = res.op[200:], res.pv[200:]
    k = kano_test(op, pv, period=op_period(op))
    ev = k.evidence()
    assert isinstance(ev, Evidence)
    assert (ev.test, ev.value, ev.vote, ev.note) == ("kano", k.index, k.vote, k.note)


@settings(max_examples=150, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 2000), seed=st.integers(0, 2**32 - 1),
       scale=st.floats(1e-6, 1e6), period=st.none() | st.floats(0.5, 3000.0),
       steps=st.booleans())
def test_random_data_never_raises(n: int, seed: int, scale: float, period: float | None,
                                  steps: bool) -> None:
    rng = np.random.default_rng(seed)
    op = scale * np.cumsum(rng.standard_normal(n))
    pv = rng.standard_normal(n) / scale
    if steps:  # quantised, stepping PV
        pv = np.round(np.cumsum(pv) * scale) / scale
    k = kano_test(op, pv, period=period)
    assert k.vote in (-1, 0, 1)
    assert isinstance(k.note, str) and k.note
