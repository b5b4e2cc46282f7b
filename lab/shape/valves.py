"""Valves for the shape corpus: several friction models in one loop bank, and lags after
the valve that give the process its higher orders.

:class:`MixedValve` steps each of ``stiction.models.valves``' models on its own loops of
one :class:`~stiction.models.simulate.LoopBank` (a bank takes one valve object; the
per-sample cost of a bank is its number of numpy calls, not its loops, so one bank of all
models is cheaper than a bank per model). :class:`LaggedValve` puts first-order lags
(up to two) after any valve: a positioner that moves the stem at a finite speed (with He's
overshoot factor K from the valve's mass, spring and viscous friction this is the physical
model, Kayihan and Doyle 2000, as its normalised equivalent: the force-balance model itself
takes 10^5 RK4 steps per simulated second) or the process's own lags in series with its
first-order-plus-dead-time part (second and third order).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from stiction._validate import FloatArray
from stiction.models.valves import ValveModel


class MixedState(NamedTuple):
    parts: tuple[Any, ...]
    x: FloatArray


@dataclasses.dataclass(frozen=True)
class MixedValve:
    """One valve model per group of loops: ``groups`` pairs the loop indices with the model
    whose parameter arrays have one entry per index. Every loop is in exactly one group."""

    n: int
    groups: Sequence[tuple[np.ndarray, ValveModel[Any]]]

    def __post_init__(self) -> None:
        seen = np.concatenate([idx for idx, _ in self.groups]) if self.groups else \
            np.empty(0, np.intp)
        if np.sort(seen).tolist() != list(range(self.n)):
            raise ValueError("every loop must be in exactly one group")

    def initial_state(self, u0: ArrayLike) -> MixedState:
        u = np.broadcast_to(np.asarray(u0, dtype=np.float64), (self.n,))
        parts = tuple(m.initial_state(u[idx].copy()) for idx, m in self.groups)
        return MixedState(parts, u.copy())

    def step(self, state: MixedState, u: ArrayLike) -> MixedState:
        u_ = np.broadcast_to(np.asarray(u, dtype=np.float64), (self.n,))
        x = np.empty(self.n)
        parts = []
        for (idx, m), s in zip(self.groups, state.parts, strict=True):
            s2 = m.step(s, u_[idx])
            x[idx] = m.position(s2)
            parts.append(s2)
        return MixedState(tuple(parts), x)

    def position(self, state: MixedState) -> FloatArray:
        return state.x


class LaggedState(NamedTuple):
    inner: Any
    lags: FloatArray  # (stages, n): each stage's output


@dataclasses.dataclass(frozen=True)
class LaggedValve:
    """``inner`` followed by first-order lags of ``taus`` (stages x loops, in samples; 0
    is no lag), each discretised exactly for a held input."""

    inner: ValveModel[Any]
    taus: FloatArray
    a: FloatArray = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.taus, dtype=np.float64)
        object.__setattr__(self, "a", np.where(t > 0, np.exp(-1.0 / np.where(t > 0, t, 1.0)),
                                               0.0))

    def initial_state(self, u0: ArrayLike) -> LaggedState:
        n = np.shape(self.taus)[1]
        s = self.inner.initial_state(np.broadcast_to(np.asarray(u0, dtype=np.float64), (n,)))
        x = self.inner.position(s)
        return LaggedState(s, np.tile(x, (np.shape(self.taus)[0], 1)))

    def step(self, state: LaggedState, u: ArrayLike) -> LaggedState:
        s = self.inner.step(state.inner, u)
        x = self.inner.position(s)
        a = self.a
        lags = np.empty_like(state.lags)
        for k in range(lags.shape[0]):
            x = a[k] * state.lags[k] + (1.0 - a[k]) * x
            lags[k] = x
        return LaggedState(s, lags)

    def position(self, state: LaggedState) -> FloatArray:
        return np.asarray(state.lags[-1])
