"""The plant view's evidence on signals whose answer is known: the nonlinearity index
(surrogate data), Granger direction and phase lag, and the bridging of gaps."""

from __future__ import annotations

import numpy as np
import pytest

from stiction.plant.direction import cycle_band, granger, net_flow, phase_lag
from stiction.plant.gaps import bridged
from stiction.plant.nonlinearity import MIN_CYCLES, nonlinearity


def _phase(n: int, period: float, rng: np.random.Generator) -> np.ndarray:
    """A cycle's phase whose period wanders (5 % jitter, as a limit cycle's does)."""
    return np.cumsum(2 * np.pi / period * (1 + 0.05 * rng.standard_normal(n)))


def _resonance(n: int, period: float, rng: np.random.Generator) -> np.ndarray:
    """A linear cycle: white noise through a narrow second-order resonance."""
    r, w = 0.985, 2 * np.pi / period
    e = rng.standard_normal(n)
    x = np.zeros(n)
    for t in range(2, n):
        x[t] = 2 * r * np.cos(w) * x[t - 1] - r * r * x[t - 2] + e[t]
    return x


def test_a_square_limit_cycle_is_nonlinear_and_a_resonance_is_not() -> None:
    rng = np.random.default_rng(4)
    n, period = 4000, 80.0
    square = np.sign(np.sin(_phase(n, period, rng))) + 0.1 * rng.standard_normal(n)
    res = nonlinearity(square, period)
    assert res is not None and res.nonlinear and res.index > 1.2, res
    linear = _resonance(n, period, rng) + 0.1 * rng.standard_normal(n)
    lin = nonlinearity(linear, period)
    assert lin is not None and not lin.nonlinear and lin.index < res.index - 1.0, lin
    assert res.cycles == 24  # the last MAX_CYCLES cycles
    assert nonlinearity(square[: int((MIN_CYCLES - 1) * period)], period) is None
    assert nonlinearity(np.zeros(n), period) is None  # flat: nothing to predict
    assert nonlinearity(square, period, seed=1) != res  # surrogates differ by seed
    assert nonlinearity(square, period) == res  # ... and are repeatable


def test_granger_finds_the_signal_that_leads() -> None:
    rng = np.random.default_rng(7)
    n, period, delay = 6000, 60.0, 9
    x = _resonance(n + delay, period, rng)
    lagged = np.convolve(x, np.ones(5) / 5, mode="full")[: n + delay]
    a = x[delay:] + 0.2 * rng.standard_normal(n)
    b = lagged[:n] + 0.2 * rng.standard_normal(n)  # b sees a's cycle 9-11 samples later
    za, zb = cycle_band(a, period), cycle_band(b, period)
    assert za.size == zb.size and abs(float(np.std(za)) - 1.0) < 1e-9
    assert granger(za, zb) > 0.1 and net_flow(za, zb) > 0.1
    assert net_flow(zb, za) == pytest.approx(-net_flow(za, zb))
    assert phase_lag(a, b, period, ts=2.0) == pytest.approx(2.0 * 11, abs=6.0)
    # an independent cycle at the same period: no gain beyond chance either way
    c = _resonance(n, period, rng) + 0.2 * rng.standard_normal(n)
    zc = cycle_band(c, period)
    assert granger(za, zc) < 0.02 and granger(zc, za) < 0.02


def test_phase_lag_folds_an_inverted_cycle() -> None:
    t = np.arange(2000.0)
    a = np.sin(2 * np.pi * t / 100)
    b = -np.sin(2 * np.pi * (t - 10) / 100)  # 10 samples later, sign turned by the path
    assert phase_lag(a, b, 100.0, ts=1.0) == pytest.approx(10.0, abs=1.0)


def test_short_gaps_are_bridged_and_long_ones_leave_with_a_reason() -> None:
    x = np.sin(np.arange(3600) / 30.0)
    one = x.copy()
    one[1000] = np.nan
    y, why = bridged(one)
    assert why is None and y is not None and np.isfinite(y).all()
    assert y[1000] == pytest.approx(x[1000], abs=1e-3)
    outage = x.copy()
    outage[2000:2030] = np.nan  # 30 s at 1 s: within 2 % of an hour's window
    y, why = bridged(outage)
    assert why is None and y is not None and np.isfinite(y).all()
    long = x.copy()
    long[2000:2200] = np.nan
    y, why = bridged(long)
    assert y is None and why == "a gap of 200 samples in its window (at most 72 are bridged)"
    sparse = x.copy()
    sparse[::5] = np.nan
    assert bridged(sparse) == (None, "720 of its 3600 samples missing (more than 10%)")
    ends = x.copy()
    ends[:100] = np.nan  # a window not yet full: held at its first value
    y, why = bridged(ends)
    assert why is None and y is not None and (y[:100] == x[100]).all()
    assert bridged(x)[0] is x
