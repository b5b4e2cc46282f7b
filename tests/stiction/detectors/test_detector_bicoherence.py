"""Bicoherence nonlinearity test (Choudhury, Shah & Thornhill): nonlinear cycles say yes,
linear loops and Gaussian noise say no, symmetric cycles abstain, bad data never raises."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stiction import Evidence, ParameterError
from stiction.detectors.bicoherence import MIN_SEGMENTS, Bicoherence, bicoherence_test
from tests.detector_helpers import ar1, loop, period

N = 3600
T = np.arange(N)


def _run(x: np.ndarray, with_period: bool = True) -> Bicoherence:
    return bicoherence_test(x, period=period(x) if with_period else None)


# --- must say yes -------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["table4-case2", "table5-case2"])
@pytest.mark.parametrize(("noise", "seed"), [(0.05, 1), (0.3, 1), (0.05, 2), (0.3, 2)])
def test_valve_sticking_more_one_way_reads_nonlinear(name: str, noise: float,
                                                     seed: int) -> None:
    # the flow loop (Table 4) and the level loop (Table 5) with a valve whose friction
    # differs with direction: an asymmetric limit cycle with phase-coupled harmonics
    lp = loop(name, n=7200 if name == "table4-case2" else N, noise=noise, seed=seed,
              asymmetric=True)
    res = _run(lp.error)
    assert res.vote == 1, res
    assert res.ngi is not None and res.ngi > 0.001
    assert res.nli is not None and res.nli > 0.3
    assert res.max_bicoherence is not None and res.max_bicoherence > 0.3


def test_sawtooth_reads_nonlinear_with_or_without_period() -> None:
    rng = np.random.default_rng(5)
    saw = (T / 40.0) % 1.0 + 0.05 * rng.standard_normal(N)
    for p in (40.0, None):
        res = bicoherence_test(saw, period=p)
        assert res.vote == 1, res
        assert res.max_bicoherence is not None and res.max_bicoherence > 0.9


# --- symmetric cycles: the bicoherence cannot judge them ---------------------------------


@pytest.mark.parametrize(("name", "noise", "seed"), [
    ("table4-case2", 0.05, 1), ("table4-case2", 0.3, 1), ("table4-case2", 0.05, 2),
    ("table4-case2", 0.3, 2), ("table5-case2", 0.05, 1), ("table5-case2", 0.05, 2),
])
def test_he_model_sticky_loop_is_symmetric_and_abstains(name: str, noise: float,
                                                        seed: int) -> None:
    # He's valve in a linear loop is odd-symmetric: the cycle has odd harmonics only and a
    # zero bispectrum. The bicoherence sees nothing (NGI < 0); the phase-locked third
    # harmonic keeps the vote at 0 instead of a false "linear".
    lp = loop(name, n=7200 if name == "table4-case2" else N, noise=noise, seed=seed)
    res = _run(lp.error)
    assert res.vote == 0, res
    assert res.ngi is not None and res.ngi < 0
    assert res.third_harmonic is not None and res.segments > 0
    assert res.third_harmonic > -math.log(0.05 / 3) / res.segments
    assert "symmetric" in res.note


def test_triangle_wave_abstains_with_period_and_reads_linear_without() -> None:
    rng = np.random.default_rng(6)
    tri = 2.0 * np.abs((T / 40.0) % 1.0 - 0.5) + 0.05 * rng.standard_normal(N)
    assert bicoherence_test(tri, period=40.0).vote == 0
    # without a period the third-harmonic check cannot run: the known blind spot
    assert bicoherence_test(tri).vote == -1


# --- must say no ----------------------------------------------------------------------------


@pytest.mark.parametrize(("name", "n", "overrides"), [
    ("aggressive-tuning", N, {}),
    ("disturbance", 14400, {}),
    ("healthy", N, {"load_sd": 0.01}),
])
@pytest.mark.parametrize("seed", [1, 2])
def test_linear_loops_read_linear(name: str, n: int, overrides: dict[str, float],
                                  seed: int) -> None:
    lp = loop(name, n=n, seed=seed, **overrides)
    res = _run(lp.error)
    assert res.vote == -1, res
    assert res.ngi is not None and res.ngi < 0


def test_gaussian_noise_and_noisy_sines_read_linear() -> None:
    # each case on 8 seeds: never nonlinear; "linear" at least 7 times in 8 (significance
    # is at 5 %, and the third-harmonic check abstains on about 1 noisy sine in 20)
    votes: dict[str, list[int]] = {}
    for seed in range(8):
        rng = np.random.default_rng(seed)
        cases = {
            "white": (rng.standard_normal(N), None),
            "ar": (ar1(N, 0.9, seed), None),
            "sine": (np.sin(2 * np.pi * T / 50.0 + seed) + 0.3 * rng.standard_normal(N), 50.0),
            "sine, off-bin period": (np.sin(2 * np.pi * T / 37.3) + rng.standard_normal(N),
                                     37.3),
        }
        for what, (x, p) in cases.items():
            votes.setdefault(what, []).append(bicoherence_test(x, period=p).vote)
    for what, vs in votes.items():
        assert 1 not in vs, (what, vs)
        assert vs.count(-1) >= 7, (what, vs)


@pytest.mark.parametrize("p", [12.0, 37.3, 50.0, 64.0, 100.0])
def test_noise_free_sine_reads_linear(p: float) -> None:
    # no noise: most bifrequencies hold rounding error and deterministic leakage, which
    # must not read as coupling (the floor under epsilon)
    res = bicoherence_test(np.sin(2 * np.pi * T / p), period=p)
    assert res.vote == -1, res
    assert res.max_bicoherence is not None and res.max_bicoherence < 0.01


def test_segments_that_start_in_phase_do_not_fake_coupling() -> None:
    # a sine with a period of exactly 25 samples: an even number of periods per segment
    # would put every segment at the same phase and leakage would read as coupling
    rng = np.random.default_rng(9)
    x = np.sin(2 * np.pi * T / 25.0) + 0.3 * rng.standard_normal(N)
    res = bicoherence_test(x, period=25.0)
    assert res.segment_length in (25, 75)  # odd multiples only
    assert res.vote == -1, res


# --- too short, degenerate data -------------------------------------------------------------


def test_few_cycles_are_too_short_to_tell() -> None:
    lp = loop("disturbance", n=N)  # 6 cycles of 600 s
    res = _run(lp.error)
    assert res.vote == 0
    assert res.segments < MIN_SEGMENTS
    assert "too short" in res.note
    assert res.ngi is None and res.nli is None


@pytest.mark.parametrize(("what", "x"), [
    ("empty", np.array([])),
    ("one sample", np.array([3.0])),
    ("31 samples", np.arange(31.0)),
    ("constant", np.full(N, 42.0)),
    ("straight line", 5.0 + 0.1 * T),
    ("zeros", np.zeros(N)),
    ("nan inside", np.where(T == 100, np.nan, np.sin(T / 7.0))),
    ("inf inside", np.where(T == 100, np.inf, np.sin(T / 7.0))),
])
def test_degenerate_data_votes_zero_without_raising(what: str, x: np.ndarray) -> None:
    res = bicoherence_test(x)
    assert res.vote == 0, (what, res)
    assert res.note


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e150, 1e300])
def test_huge_and_tiny_magnitudes_give_the_same_answer(scale: float) -> None:
    lp = loop("table5-case2", n=N, asymmetric=True)
    x = lp.error
    ref = _run(x)
    res = bicoherence_test(x * scale, period=period(x))
    assert res.vote == ref.vote == 1
    assert res.nli == pytest.approx(ref.nli, rel=1e-6)


# --- units ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("gain", "offset"), [(7.0, 300.0), (0.01, -5.0), (-3.0, 1e4)])
def test_no_unit_assumptions(gain: float, offset: float) -> None:
    for lp in (loop("table5-case2", n=N, asymmetric=True), loop("table4-case2", n=7200),
               loop("aggressive-tuning", n=N)):
        x = lp.error
        p = period(x)
        ref = bicoherence_test(x, period=p)
        res = bicoherence_test(gain * x + offset, period=p)
        assert res.vote == ref.vote
        for f in ("ngi", "nli", "tnli", "max_bicoherence", "third_harmonic"):
            assert getattr(res, f) == pytest.approx(getattr(ref, f), rel=1e-6, abs=1e-9), f


# --- parameters and the result --------------------------------------------------------------


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan"), float("inf"), "ten"])
def test_bad_period_is_named(bad: object) -> None:
    with pytest.raises(ParameterError, match="`period`") as info:
        bicoherence_test(np.zeros(100), period=bad)  # type: ignore[arg-type]
    assert info.value.name == "period"


@pytest.mark.parametrize("fast", [1.98, 3.9])
def test_oscillation_faster_than_four_samples_votes_zero(fast: float) -> None:
    # the ACF can report a 2-sample "period" on noise: data, not a bad parameter
    rng = np.random.default_rng(1)
    res = bicoherence_test(rng.standard_normal(N), period=fast)
    assert res.vote == 0
    assert "too fast" in res.note


def test_two_dimensional_signal_is_named() -> None:
    with pytest.raises(ParameterError, match="`x` must be 1-D") as info:
        bicoherence_test(np.zeros((10, 10)))
    assert info.value.name == "x"


def test_evidence_carries_nli_vote_and_note() -> None:
    res = _run(loop("table5-case2", n=N, asymmetric=True).error)
    ev = res.evidence()
    assert isinstance(ev, Evidence)
    assert ev == Evidence("bicoherence", res.nli, 1, res.note)
    short = bicoherence_test(np.ones(10)).evidence()
    assert short.value is None and short.vote == 0


# --- property: any finite data --------------------------------------------------------------

_FIELDS = ("ngi", "nli", "tnli", "max_bicoherence", "critical", "third_harmonic")


@settings(max_examples=120, deadline=None, derandomize=True, database=None)
@given(
    x=hnp.arrays(np.float64, st.integers(0, 2000),
                 elements=st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)),
    scale=st.sampled_from([1.0, 1e-200, 1e200]),
    p=st.one_of(st.none(), st.floats(0.01, 500.0)),
)
def test_any_finite_record_gives_a_vote(x: np.ndarray, scale: float, p: float | None) -> None:
    with np.errstate(over="ignore"):
        scaled = x * scale
    res = bicoherence_test(scaled if np.all(np.isfinite(scaled)) else x, period=p)
    assert res.vote in (-1, 0, 1)
    assert isinstance(res.note, str) and res.note
    for f in _FIELDS:
        val = getattr(res, f)
        assert val is None or math.isfinite(val), (f, val)
