"""Apparent stiction band from the OP-PV pattern (stiction.detectors.ellipse, Choudhury et
al. 2006)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from detector_fixtures import cached_sim
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stiction import Evidence, ParameterError
from stiction.detectors.ellipse import THIN, ellipse_band
from stiction.scenarios import SimResult
from stiction.signal.oscillation import detect_oscillation


def _window(res: SimResult, skip: int = 200) -> tuple[np.ndarray, np.ndarray, float]:
    op, pv = res.op[skip:], res.pv[skip:]
    osc = detect_oscillation(op)
    assert osc.oscillating and osc.period is not None
    return op, pv, osc.period


def _band_op(res: SimResult) -> float:
    """The OP swing between valve jumps of the simulated He valve, % of span: S = 2 fs - J."""
    sc = res.scenario
    return 100.0 * (2.0 * sc.fs - sc.k * (sc.fs - sc.fd))


# --- analytic cases ---------------------------------------------------------------------------


@pytest.mark.parametrize("lag_deg", [0.0, 30.0, 60.0, 90.0, 120.0, 175.0])
def test_sinusoids_give_the_ellipse_of_their_phase(lag_deg: float) -> None:
    """OP = A sin, PV = B sin(. - lag): the ellipse's width at PV's centre is 2 A |sin(lag)|,
    whatever B, and the phase comes out as the lag."""
    t = np.arange(4000.0)
    period = 100.0
    w = 2 * np.pi * t / period
    op = 3.0 * np.sin(w)
    pv = 0.2 * np.sin(w - math.radians(lag_deg))
    fit = ellipse_band(op, pv, period=period)
    assert fit.band is not None
    # to 1 % of the OP swing (a line is the limit the ellipse fit only approaches)
    assert fit.band == pytest.approx(2 * 3.0 * abs(math.sin(math.radians(lag_deg))), abs=0.06)
    assert fit.amplitude == pytest.approx(3.0, rel=0.01)
    assert fit.phase_deg == pytest.approx(lag_deg, abs=1.0)
    assert fit.coherence == pytest.approx(1.0, abs=1e-3)
    assert fit.vote == (-1 if abs(math.sin(math.radians(lag_deg))) < THIN else 0)


def test_integrating_pattern_uses_the_rate_of_change_of_pv() -> None:
    """PV the integral of OP (a linear valve on a tank): the OP-PV ellipse is a circle, the
    OP-dPV/dt one a line."""
    t = np.arange(4000.0)
    op = np.sin(2 * np.pi * t / 80.0)
    pv = np.cumsum(op)
    assert ellipse_band(op, pv, period=80.0).width_ratio == pytest.approx(1.0, abs=0.02)
    line = ellipse_band(op, pv, period=80.0, integrating=True)
    assert line.width_ratio is not None
    assert line.width_ratio < 0.1
    assert line.vote == -1


# --- simulated loops --------------------------------------------------------------------------


@pytest.mark.parametrize(("noise", "seed"), [(0.05, 1), (0.05, 2), (0.5, 1), (0.5, 2)])
def test_sticky_flow_loop_band_within_15_percent(noise: float, seed: int) -> None:
    """He & Wang's Table 4 case 2 (fs 0.30, fd 0.27, K 1.99): the band is the OP swing
    between jumps, S = 2 fs - J = 54 % of span, within 15 %. The shape does not call it."""
    res = cached_sim("table4-case2", noise, seed)
    op, pv, period = _window(res)
    fit = ellipse_band(op, pv, period=period)
    assert fit.band is not None
    assert abs(fit.band - _band_op(res)) <= 0.15 * _band_op(res), fit
    assert fit.width_ratio is not None
    assert fit.width_ratio > 0.7
    assert fit.vote == 0
    assert "band" in fit.note


@pytest.mark.parametrize("seed", [1, 2])
def test_sticky_level_loop_band_within_25_percent(seed: int) -> None:
    """Table 5 case 2 (integrating): OP against dPV/dt; the band within 25 % of S (OP's
    proportional kicks carry part of its swing)."""
    res = cached_sim("table5-case2", 0.05, seed)
    op, pv, period = _window(res, skip=800)
    fit = ellipse_band(op, pv, period=period, integrating=True)
    assert fit.band is not None
    assert abs(fit.band - _band_op(res)) <= 0.25 * _band_op(res), fit
    assert fit.vote == 0


@pytest.mark.parametrize(("noise", "seed", "load_sd"),
                         [(0.05, 1, 0.0), (0.05, 2, 0.0), (0.2, 1, 0.02), (0.2, 2, 0.02)])
def test_aggressive_tuning_is_a_thin_ellipse(noise: float, seed: int, load_sd: float) -> None:
    res = cached_sim("aggressive-tuning", noise, seed, load_sd=load_sd or 0.01)
    op, pv, period = _window(res)
    fit = ellipse_band(op, pv, period=period)
    assert fit.vote == -1, fit
    assert "thin" in fit.note


@pytest.mark.parametrize(("name", "kw"), [
    ("healthy", {"load_sd": 0.005, "load_tau": 30.0}),
    ("healthy", {"load_sd": 0.02, "load_tau": 600.0}),
    ("disturbance", {}),
    ("disturbance", {"load_sd": 0.01, "load_tau": 200.0}),
])
def test_linear_loops_never_say_yes(name: str, kw: dict[str, float]) -> None:
    """Wide ellipses from a disturbance are the controller's doing: the test gives a band
    and no vote for stiction."""
    for seed in (1, 2):
        res = cached_sim(name, 0.05, seed, **kw)
        op, pv = res.op[200:], res.pv[200:]
        osc = detect_oscillation(op)
        period = osc.period if osc.oscillating and osc.period else 600.0
        fit = ellipse_band(op, pv, period=period)
        assert fit.vote in (-1, 0), fit


# --- units, degenerate data, parameters --------------------------------------------------------


def test_units_do_not_matter_and_the_band_scales_with_op() -> None:
    res = cached_sim("table4-case2", 0.05, 1)
    op, pv, period = _window(res)
    a = ellipse_band(op, pv, period=period)
    b = ellipse_band(7.0 * op + 300.0, 0.01 * pv - 5.0, period=period)
    assert a.band is not None and b.band is not None
    assert b.band == pytest.approx(7.0 * a.band, rel=1e-6)
    assert b.amplitude == pytest.approx(7.0 * a.amplitude, rel=1e-6)  # type: ignore[operator]
    for name in ("width_ratio", "phase_deg", "coherence", "band_share"):
        assert getattr(b, name) == pytest.approx(getattr(a, name), rel=1e-6, abs=1e-9), name
    assert (a.vote, a.note.split(":")[0]) == (b.vote, b.note.split(":")[0])
    # a falling PV (reverse-acting process) changes the phase, not the band or the vote
    c = ellipse_band(op, -pv, period=period)
    assert c.band == pytest.approx(a.band, rel=1e-6)
    assert c.vote == a.vote


@pytest.mark.parametrize(("op", "pv"), [
    (np.zeros(500), np.zeros(500)),
    (np.ones(500), np.sin(np.arange(500.0))),
    (np.sin(np.arange(500.0) / 8), np.full(500, 3.0)),
    (np.empty(0), np.empty(0)),
    (np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 1.0])),
    (1e300 * np.sin(np.arange(800.0) / 8), 1e-300 * np.cos(np.arange(800.0) / 8)),
    (np.full(800, np.nan), np.zeros(800)),
])
def test_degenerate_data_votes_zero(op: np.ndarray, pv: np.ndarray) -> None:
    fit = ellipse_band(op, pv, period=50.0)
    assert fit.vote == 0
    assert fit.note


def test_bad_parameters_name_the_argument() -> None:
    x = np.sin(np.arange(400.0) / 10)
    for bad in (0, -3.0, float("nan"), float("inf"), "ten", None, True):
        with pytest.raises(ParameterError, match="period"):
            ellipse_band(x, x, period=bad)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="integrating"):
        ellipse_band(x, x, period=40.0, integrating="yes")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="pv"):
        ellipse_band(x, x[:-1], period=40.0)


def test_evidence() -> None:
    res = cached_sim("aggressive-tuning", 0.05, 1, load_sd=0.01)
    op, pv, period = _window(res)
    fit = ellipse_band(op, pv, period=period)
    ev = fit.evidence()
    assert isinstance(ev, Evidence)
    assert (ev.test, ev.value, ev.vote, ev.note) == ("ellipse", fit.width_ratio, fit.vote,
                                                     fit.note)


@settings(max_examples=150, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 2000), seed=st.integers(0, 2**32 - 1),
       scale=st.floats(1e-6, 1e6), period=st.floats(0.5, 3000.0),
       integrating=st.booleans())
def test_random_data_never_raises(n: int, seed: int, scale: float, period: float,
                                  integrating: bool) -> None:
    rng = np.random.default_rng(seed)
    op = scale * np.cumsum(rng.standard_normal(n))
    pv = rng.standard_normal(n) / scale
    if n and seed % 3 == 0:
        pv = np.round(pv, 1)  # quantised
    fit = ellipse_band(op, pv, period=period, integrating=integrating)
    assert fit.vote in (-1, 0, 1)
    assert isinstance(fit.note, str) and fit.note
