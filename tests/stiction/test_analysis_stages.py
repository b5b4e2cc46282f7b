"""Unit tests of the analysis stages on literal / analytic signals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from stiction._detect import noise_sd, stiction_index
from stiction._oscillation import acf, detect_oscillation
from stiction._quantify import quantify
from stiction._segments import exp_basis, prefix, rss
from stiction._smooth import smooth
from stiction._switching import find_switches

RNG = np.random.default_rng(42)
T = np.arange(3000.0)
SINE = np.sin(2 * np.pi * T / 200.0)
TRIANGLE = signal.sawtooth(2 * np.pi * T / 200.0, width=0.5)


# ------------------------------------------------------------------------- smoothing
def test_smooth_reduces_noise() -> None:
    y = SINE + RNG.normal(0, 0.2, T.size)
    z, s = smooth(y)
    assert s > 0
    assert np.std(z - SINE) < 0.3 * np.std(y - SINE)


def test_robust_smooth_ignores_outliers() -> None:
    y = SINE + RNG.normal(0, 0.05, T.size)
    y[::97] += 8.0
    z_plain, _ = smooth(y)
    z_rob, _ = smooth(y, robust=True)
    assert np.std(z_rob - SINE) < 0.05
    assert np.std(z_rob - SINE) < 0.5 * np.std(z_plain - SINE)


def test_smooth_fills_missing_values() -> None:
    y = SINE.copy()
    w = np.ones_like(y)
    y[1000:1040] = np.nan
    w[1000:1040] = 0
    z, _ = smooth(y, weights=w)
    assert np.all(np.isfinite(z))
    assert np.max(np.abs(z[1000:1040] - SINE[1000:1040])) < 0.15  # a fifth of a period
    assert np.max(np.abs(z[:900] - SINE[:900])) < 0.02


def test_smooth_fixed_s_passes_a_line() -> None:
    y = 3.0 + 0.01 * T[:200]
    z, _ = smooth(y, s=1e3)
    assert np.allclose(z[5:-5], y[5:-5], atol=1e-2)


# ----------------------------------------------------------------------- oscillation
def test_acf_of_sine_is_cosine() -> None:
    r = acf(SINE)
    assert r[0] == pytest.approx(1.0)
    assert r[100] == pytest.approx(-1.0, abs=0.1)


def test_oscillation_period_of_a_noisy_sine() -> None:
    osc = detect_oscillation(SINE + RNG.normal(0, 0.5, T.size))
    assert osc.oscillating
    assert osc.period == pytest.approx(200.0, rel=0.02)


def test_white_noise_does_not_oscillate() -> None:
    osc = detect_oscillation(RNG.normal(0, 1, T.size))
    assert not osc.oscillating
    assert "irregular" in osc.reason or "crosses zero" in osc.reason


def test_white_noise_never_passes_as_an_oscillation() -> None:
    """Now and then the ACF zero crossings of noise are even enough to pass Thornhill's
    regularity test; the significance test of the ACF lobe turns those down."""
    rng = np.random.default_rng(7)
    for n in (600, 1800, 3600):
        for _ in range(100):
            osc = detect_oscillation(rng.normal(0, 1, n))
            assert not osc.oscillating, osc


def test_a_noisy_real_oscillation_is_significant() -> None:
    """A sine as strong as the noise (SD 0.71 vs 1): whenever its crossings are regular,
    the lobe test lets it through (it stands at about 0.33 sqrt(n) = 20)."""
    t = np.arange(3600.0)
    rng = np.random.default_rng(3)
    for _ in range(20):
        osc = detect_oscillation(np.sin(2 * np.pi * t / 200.0) + rng.normal(0, 1, t.size))
        assert "significant" not in osc.reason
        if osc.oscillating:
            assert osc.period == pytest.approx(200.0, rel=0.05)


def test_a_ramp_does_not_oscillate() -> None:
    assert not detect_oscillation(0.01 * T + RNG.normal(0, 0.01, T.size)).oscillating


# ------------------------------------------------------------------------ detection
@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_si_of_triangle_and_sine(noise: float) -> None:
    tri = stiction_index(TRIANGLE + RNG.normal(0, noise, T.size), 200.0)
    sin = stiction_index(SINE + RNG.normal(0, noise, T.size), 200.0)
    assert tri.si is not None
    assert sin.si is not None
    assert tri.si >= 0.9
    assert sin.si <= 0.1
    assert tri.half_periods >= 25


def test_si_not_resolved_when_both_shapes_fit_within_the_noise() -> None:
    # amplitude 1 under noise SD 2: the triangle's and the sine's misfits differ by ~0.003
    # per sample, which noise of variance 4 drowns; under noise SD 0.1 they stand out
    rng = np.random.default_rng(5)
    for _ in range(10):
        for base in (TRIANGLE, SINE):
            assert not stiction_index(base + rng.normal(0, 2.0, T.size), 200.0).resolved
    tri = stiction_index(TRIANGLE + rng.normal(0, 0.1, T.size), 200.0)
    sin = stiction_index(SINE + rng.normal(0, 0.1, T.size), 200.0)
    assert tri.resolved and sin.resolved
    assert tri.si is not None and tri.si >= 0.9
    assert sin.si is not None and sin.si <= 0.2


def test_noise_sd_estimate() -> None:
    assert noise_sd(SINE + RNG.normal(0, 0.3, T.size)) == pytest.approx(0.3, rel=0.1)


# --------------------------------------------------------------------- prefix fits
def test_prefix_rss_matches_lstsq() -> None:
    t = np.arange(100.0)
    y = 2 + np.exp(-t / 7) + RNG.normal(0, 0.1, t.size)
    x = exp_basis(t, 0.0, 7.0)
    r, coef = rss(prefix(x, y), np.array([10, 0]), np.array([90, 100]))
    for k, (i, j) in enumerate([(10, 90), (0, 100)]):
        c, res, *_ = np.linalg.lstsq(x[i:j], y[i:j], rcond=None)
        assert coef[k] == pytest.approx(c, rel=1e-6)
        assert r[k] == pytest.approx(res[0], rel=1e-6)


# ---------------------------------------------------- switching points, multi-jump
def _first_order(u: np.ndarray, tau: float) -> np.ndarray:
    a = np.exp(-1.0 / tau)
    return signal.lfilter([0.0, 1.0 - a], [1.0, -a], u, zi=[a * u[0]])[0]


def _square_vp(n: int, half: int, double: bool) -> tuple[np.ndarray, np.ndarray]:
    """VP (%) alternating 48/52 every ``half`` samples; ``double``: each move in two steps
    of 2 %, the second 60 samples after the first."""
    vp = np.full(n, 50.0)
    jumps = np.arange(100, n, half)
    level = 48.0
    for k, j in enumerate(jumps):
        level = 52.0 if k % 2 == 0 else 48.0
        if double:
            vp[j:] = level - (2.0 if k % 2 == 0 else -2.0)
            vp[j + 60:] = level + (2.0 if k % 2 == 0 else -2.0)
        else:
            vp[j:] = level
    return vp, jumps


@pytest.mark.parametrize("tau", [20.0, 150.0])
def test_switches_of_a_filtered_square_wave(tau: float) -> None:
    vp, jumps = _square_vp(6000, 500, double=False)
    pv = 50 + _first_order(vp - 50, tau) + RNG.normal(0, 0.02, vp.size)
    sw = find_switches(pv, 1000.0, integrating=False)
    assert sw is not None
    assert sw.tau == pytest.approx(tau, rel=0.05)
    err = [np.min(np.abs(jumps - c)) for c in sw.onsets]
    assert max(err) <= 2.0


def test_switches_of_an_integrated_square_wave() -> None:
    vp, jumps = _square_vp(6000, 500, double=False)
    pv = 50 + np.cumsum(vp - 50) * 0.01 + RNG.normal(0, 0.02, vp.size)
    sw = find_switches(pv, 1000.0, integrating=True)
    assert sw is not None
    assert sw.tau is None
    err = [np.min(np.abs(jumps - c)) for c in sw.onsets]
    assert max(err) <= 2.0
    assert np.median(np.abs(np.diff(sw.b))) == pytest.approx(0.01 * 4.0, rel=0.05)


@pytest.mark.parametrize(("double", "expected"), [(False, False), (True, True)])
def test_multi_jump_check(double: bool, expected: bool) -> None:
    vp, _ = _square_vp(6000, 500, double=double)
    pv = 50 + _first_order(vp - 50, 100.0) + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 100) / 1000.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.reason is None
    assert q.multi_jump is expected


def test_pv_creeping_between_single_jumps_is_not_multi_jump() -> None:
    """Plant PV rarely relaxes as one clean exponential: here it creeps back by a third of
    the swing between jumps (a slow load, a valve that creeps). That spoils the fit
    (``poor_fit``) but is no second jump, so ``multi_jump`` stays False."""
    vp, _ = _square_vp(6000, 500, double=False)
    phase = (np.arange(vp.size) - 100) % 500 / 500.0
    creep = -1.3 * np.sign(vp - 50) * phase  # drifts back towards the middle
    pv = 50 + _first_order(vp - 50, 100.0) + creep + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 100) / 1000.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.reason is None
    assert q.poor_fit >= 8  # of 10 half cycles
    assert q.multi_jump is False
    # OP swing 20 between the jumps, J = 4: fs = 12, fd = 12 - 4 / 1.99; fd reads OP only
    assert q.fd_op == pytest.approx(12 - 4 / 1.99, rel=0.01)
    assert q.fs_op == pytest.approx(12, rel=0.1)


def test_inconsistent_sizes_are_refused_not_reported() -> None:
    """When the PV switching points are not where OP turned (here OP is a sawtooth whose
    swing between the switches is ~0 while PV steps by 4), fd would come out <= 0: the
    quantification says so instead of reporting it."""
    vp, _ = _square_vp(6000, 500, double=False)
    pv = 50 + _first_order(vp - 50, 30.0) + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 350) / 500.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.fd_op is None
    assert q.reason is not None and "inconsistent sizes" in q.reason
