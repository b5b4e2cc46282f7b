"""The hot-path helpers that replace library calls must give the library's values bit for
bit: the bounded minimiser (scipy.optimize.fminbound) and the array statistics (ndarray
methods)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from stiction.signal.arrays import mean, std
from stiction.signal.bounded import fminbound

RNG = np.random.default_rng(7)


@pytest.mark.parametrize("xtol", [1e-5, 1e-3, 1e-2])
def test_fminbound_is_scipys(xtol: float) -> None:
    for _ in range(300):
        c, w, ph = RNG.uniform(-3.0, 8.0), RNG.uniform(0.1, 5.0), RNG.uniform(0.0, 6.0)
        kind = int(RNG.integers(0, 4))

        def f(x: float, c: float = c, w: float = w, ph: float = ph, kind: int = kind
              ) -> float:
            x = float(x)
            v = [(x - c) ** 2 / w, abs(x - c), math.sin(3 * x + ph) + 0.1 * x * x,
                 (x - c) ** 4 - (x - c) ** 2][kind]
            return v + 0.1 * math.sin(50 * x)

        lo, hi = math.log(0.2), math.log(20.0 * RNG.uniform(8.0, 2000.0))
        assert fminbound(f, lo, hi, xtol=xtol) == float(optimize.fminbound(f, lo, hi,
                                                                            xtol=xtol))


def test_mean_and_std_are_numpys() -> None:
    for k in range(500):
        n = int(RNG.integers(1, 5000))
        x = RNG.standard_normal(n) * 10.0 ** RNG.uniform(-5, 5) + RNG.uniform(-1e3, 1e3)
        if k % 3 == 0:
            x = x[:: int(RNG.integers(1, 5))]
        if k % 5 == 0:
            x = np.cumsum(x)
        assert mean(x) == float(x.mean())
        assert std(x) == float(x.std())
