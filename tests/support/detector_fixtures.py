"""Simulations the stiction tests share: each scenario run once per test process, the period
of OP's oscillation as the analysis would find it, and a sticky loop as a CSV file."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from stiction.scenarios import SimResult, scenario, simulate
from stiction.signal.oscillation import detect_oscillation


@functools.cache
def cached_sim(name: str, noise: float, seed: int, **kw: float) -> SimResult:
    """``simulate(scenario(name, **kw), noise=noise, seed=seed)``, cached."""
    return simulate(scenario(name, **kw), noise=noise, seed=seed)


def op_period(op: np.ndarray) -> float | None:
    """OP's oscillation period in samples, None when it does not oscillate."""
    osc = detect_oscillation(op)
    return osc.period if osc.oscillating else None


def write_loop_csv(directory: Path) -> Path:
    """A sticky loop (table4-case2, PV noise 0.02) as ``directory/loop.csv`` with columns
    t, op, pv, as ``stiction analyze`` reads it."""
    res = simulate("table4-case2", noise=0.02, seed=4)
    path = directory / "loop.csv"
    rows = np.column_stack([res.t, res.op, res.pv])
    np.savetxt(path, rows, delimiter=",", header="t,op,pv", comments="", fmt="%.9g")
    return path
