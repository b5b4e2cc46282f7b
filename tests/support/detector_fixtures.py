"""Simulations the detector tests share: each scenario run once per test process, and the
period of OP's oscillation as the analysis would find it."""

from __future__ import annotations

import functools

import numpy as np

from stiction._oscillation import detect_oscillation
from stiction.scenarios import SimResult, scenario, simulate


@functools.cache
def cached_sim(name: str, noise: float, seed: int, **kw: float) -> SimResult:
    """``simulate(scenario(name, **kw), noise=noise, seed=seed)``, cached."""
    return simulate(scenario(name, **kw), noise=noise, seed=seed)


def op_period(op: np.ndarray) -> float | None:
    """OP's oscillation period in samples, None when it does not oscillate."""
    osc = detect_oscillation(op)
    return osc.period if osc.oscillating else None
