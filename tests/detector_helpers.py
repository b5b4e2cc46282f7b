"""Simulated loops for the detector tests (bicoherence, Horch): the scenarios of
:mod:`stiction.scenarios` after their start-up transient, and the same loops with a valve
that sticks more one way than the other."""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from stiction.models.simulate import LoopBank
from stiction.scenarios import scenario
from stiction.signal.oscillation import detect_oscillation

SKIP = 600  # samples dropped: the set-point step that starts every scenario, and its ringing


class _State(NamedTuple):
    x: np.ndarray


class AsymmetricValve:
    """He's semiphysical valve (k = 1.99) whose static and dynamic friction differ with the
    direction of travel, as with a spring-return actuator: the limit cycle is no longer
    half-wave symmetric."""

    def __init__(self, fs_up: float, fd_up: float, fs_down: float, fd_down: float) -> None:
        self.up = (fs_up, fd_up)
        self.down = (fs_down, fd_down)

    def initial_state(self, u0: ArrayLike) -> _State:
        return _State(np.array(u0, dtype=np.float64, copy=True))

    def step(self, state: _State, u: ArrayLike) -> _State:
        e = np.asarray(u, dtype=np.float64) - state.x
        rising = e > 0
        fs = np.where(rising, self.up[0], self.down[0])
        fd = np.where(rising, self.up[1], self.down[1])
        moved = state.x + 1.99 * (e - np.sign(e) * fd)
        return _State(np.where(np.abs(e) > fs, moved, state.x))

    def position(self, state: _State) -> np.ndarray:
        return state.x


class Loop(NamedTuple):
    sp: np.ndarray
    op: np.ndarray
    pv: np.ndarray

    @property
    def error(self) -> np.ndarray:
        return self.sp - self.pv


@functools.cache
def loop(name: str, *, n: int, noise: float = 0.05, seed: int = 1, asymmetric: bool = False,
         **overrides: Any) -> Loop:
    """``n`` samples of scenario ``name`` (with ``overrides``) after its start-up."""
    sc = scenario(name, **overrides)
    valve = AsymmetricValve(0.30, 0.27, 0.15, 0.10) if asymmetric else sc.valve()
    bank = LoopBank(1, sc.loop_params(noise), valve, ts=sc.ts, seed=seed)
    out = np.empty((3, n + SKIP))
    for i in range(n + SKIP):
        sp = 50.0 + (sc.sp_step if i * sc.ts >= sc.sp_step_time else 0.0)
        step = bank.step(sp)
        out[:, i] = (step.sp[0], step.op[0], step.pv[0])
    return Loop(*(row[SKIP:] for row in out))


def period(x: np.ndarray) -> float | None:
    """The oscillation period the caller would pass (None when not oscillating)."""
    osc = detect_oscillation(x)
    return osc.period if osc.oscillating else None


def ar1(n: int, a: float, seed: int) -> np.ndarray:
    """Gaussian AR(1) noise."""
    rng = np.random.default_rng(seed)
    e = rng.standard_normal(n)
    y = np.empty(n)
    y[0] = e[0]
    for k in range(1, n):
        y[k] = a * y[k - 1] + e[k]
    return y
