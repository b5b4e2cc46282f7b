"""Valve stiction models as explicit-state steps.

Every model here has the same small interface (python-control style, state first)::

    state = model.initial_state(u0)        # valve at rest at input u0
    state = model.step(state, u)           # one sample (zero-order hold) later
    x = model.position(state)

``u`` and ``u0`` are scalars or arrays; with arrays every element is an independent valve,
and the model's parameters broadcast against them, so one call steps thousands of valves.
States are immutable tuples of arrays: a step never mutates its input.

Data-driven models (He, Choudhury, Kano) work on fractions of the valve span: u' = OP/span,
x' = VP/span (He & Wang 2014, Table 2). The physical model works in SI units.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple, Protocol, TypeVar, cast

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray

__all__ = [
    "PSI",
    "ChoudhuryValve",
    "HeValve",
    "KanoValve",
    "PhysicalParams",
    "PhysicalValve",
    "ValveModel",
    "k_from_physical",
]

PSI = 6894.757293168361
"""One pound per square inch in pascal."""

S = TypeVar("S")


class ValveModel(Protocol[S]):
    """The interface every valve model implements."""

    def initial_state(self, u0: ArrayLike) -> S: ...

    def step(self, state: S, u: ArrayLike) -> S: ...

    def position(self, state: S) -> FloatArray: ...


# ---------------------------------------------------------------------------------------------
# He's semiphysical model (He, Wang, Pottmann & Qin 2007; He & Wang 2014 section 2.2)


class HeState(NamedTuple):
    x: FloatArray
    """Valve position, fraction of span."""


@dataclasses.dataclass(frozen=True)
class HeValve:
    """He's semiphysical model with static friction ``fs``, dynamic friction ``fd`` and
    overshoot factor ``k`` (He & Wang 2014, eq 6).

    Per sample, with net force e = u(t) - x(t-1): if |e| > fs the valve slips to
    x(t-1) + k·(e - sign(e)·fd), otherwise it stays. ``k = 1`` is He's original model;
    ``fs = fd = 0`` with ``k = 1`` is a perfect valve. ``k`` is 1.99 for the Table 1 valve
    (see :func:`k_from_physical`). ``fs``, ``fd`` and ``k`` may be arrays (one per valve).
    """

    fs: ArrayLike
    fd: ArrayLike
    k: ArrayLike = 1.99

    def __post_init__(self) -> None:
        fs = v.non_negative("fs", self.fs)
        fd = v.non_negative("fd", self.fd)
        k = v.finite("k", self.k)
        if np.any(fd > fs):
            raise ParameterError("fd", f"must not exceed fs (fd={self.fd!r}, fs={self.fs!r})")
        if np.any((k < 1) | (k > 2)):
            raise ParameterError("k", f"must lie in [1, 2], was {self.k!r}")
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "fd", fd)
        object.__setattr__(self, "k", k)

    def initial_state(self, u0: ArrayLike) -> HeState:
        return HeState(np.array(u0, dtype=np.float64, copy=True))

    def step(self, state: HeState, u: ArrayLike) -> HeState:
        fs, fd, k = cast(FloatArray, self.fs), cast(FloatArray, self.fd), cast(FloatArray, self.k)
        x = state.x
        e = np.asarray(u, dtype=np.float64) - x
        slip = np.abs(e) > fs
        moved = x + k * (e - np.sign(e) * fd)
        return HeState(np.where(slip, moved, x))

    def position(self, state: HeState) -> FloatArray:
        return state.x


def k_from_physical(m: float, k: float, fv: float) -> float:
    """Overshoot factor K of the semiphysical model from the valve's physics (eq 5).

    K = 1 + exp(-pi·a / sqrt(1 - a^2)) with a^2 = fv^2 / (4·k·m): mass ``m`` (kg), spring
    constant ``k`` (N/m) and viscous friction ``fv`` (kg/s). Table 1 gives K = 1.99.
    """
    m_ = v.positive_scalar("m", m)
    k_ = v.positive_scalar("k", k)
    fv_ = float(v.non_negative("fv", fv))
    a2 = fv_**2 / (4.0 * k_ * m_)
    if a2 >= 1.0:
        return 1.0  # critically or over-damped: no overshoot
    a = math.sqrt(a2)
    return 1.0 + math.exp(-math.pi * a / math.sqrt(1.0 - a2))


# ---------------------------------------------------------------------------------------------
# Kayihan & Doyle (2000) physical model, paper eqs 1-4, Table 1


@dataclasses.dataclass(frozen=True)
class PhysicalParams:
    """Physical valve parameters; defaults are the paper's Table 1."""

    sa: float = 6.45e-2  # diaphragm area, m^2
    k: float = 5.25e4  # spring constant, N/m
    m: float = 1.36  # moving mass, kg
    fc: float = 1423.0  # Coulomb (dynamic) friction, N
    fs: float = 1708.0  # static friction, N
    fv: float = 1.59  # viscous friction, kg/s
    vs: float = 2.54e-4  # Stribeck velocity, m/s
    xm: float = 0.1016  # valve travel span, m

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name in {"fc", "fs", "fv"}:
                v.non_negative(f.name, getattr(self, f.name))
            else:
                v.positive_scalar(f.name, getattr(self, f.name))
        if self.fc > self.fs:
            raise ParameterError("fc", f"must not exceed fs (fc={self.fc}, fs={self.fs})")

    @property
    def pressure_span(self) -> float:
        """Air pressure (Pa) that moves a frictionless valve over its full travel xm."""
        return self.k * self.xm / self.sa

    def normalised(self) -> tuple[float, float, float]:
        """(fs, fd, K) of the equivalent semiphysical model (paper Table 2 and eq 5)."""
        scale = self.k * self.xm
        return self.fs / scale, self.fc / scale, k_from_physical(self.m, self.k, self.fv)


class PhysicalState(NamedTuple):
    x: FloatArray  # stem position, m
    v: FloatArray  # stem velocity, m/s
    moving: NDArrayBool  # True while slipping


NDArrayBool = np.ndarray


@dataclasses.dataclass(frozen=True)
class PhysicalValve:
    """Kayihan & Doyle (2000) force-balance model, m·x'' = Sa·u - k·x + Ff.

    The stick/slip switch is an event-driven state machine, not a smoothed friction law:
    a stuck valve stays put while |Sa·u - k·x| <= Fs (friction balances the net force
    exactly); above Fs it breaks away and the motion, with Coulomb, viscous and Stribeck
    friction, is integrated by fixed-step RK4 of ``substep`` seconds until the velocity
    crosses zero. There the crossing is located by linear interpolation and the valve sticks
    if the net force is within Fs, else it moves on in the direction of the net force.
    Within a moving phase the direction of friction is held fixed, so the discontinuity of
    sign(v) is never integrated across. ``u`` is the air pressure in Pa, held for ``dt`` s.
    """

    params: PhysicalParams = dataclasses.field(default_factory=PhysicalParams)
    dt: float = 1.0
    substep: float = 1e-5

    def __post_init__(self) -> None:
        v.positive_scalar("dt", self.dt)
        v.positive_scalar("substep", self.substep)

    def initial_state(self, u0: ArrayLike) -> PhysicalState:
        """At rest where a frictionless valve would sit for pressure ``u0``, clipped to travel."""
        p = self.params
        x = np.clip(p.sa * np.asarray(u0, dtype=np.float64) / p.k, 0.0, p.xm)
        return PhysicalState(np.array(x, copy=True), np.zeros_like(x), np.zeros(x.shape, bool))

    def position(self, state: PhysicalState) -> FloatArray:
        return state.x

    def _accel(self, x: FloatArray, vel: FloatArray, fa: FloatArray, s: FloatArray) -> FloatArray:
        p = self.params
        friction = s * (p.fc + (p.fs - p.fc) * np.exp(-((vel / p.vs) ** 2))) + p.fv * vel
        return np.asarray((fa - p.k * x - friction) / p.m)

    def step(self, state: PhysicalState, u: ArrayLike) -> PhysicalState:
        p = self.params
        shape = state.x.shape
        fa = np.broadcast_to(p.sa * np.asarray(u, dtype=np.float64), shape).ravel()
        x = state.x.ravel().copy()
        vel = state.v.ravel().copy()
        moving = state.moving.ravel().copy()
        net = fa - p.k * x
        # direction of motion: from the velocity while moving, from the net force at rest
        s = np.where(moving, np.sign(vel), np.sign(net))
        breakaway = ~moving & (np.abs(net) > p.fs)
        moving |= breakaway
        h = self.substep
        n_sub = round(self.dt / h)
        for _ in range(n_sub):
            if not moving.any():
                break
            idx = np.flatnonzero(moving)
            xi, vi, fi, si = x[idx], vel[idx], fa[idx], s[idx]
            k1x, k1v = vi, self._accel(xi, vi, fi, si)
            hh = 0.5 * h
            k2x, k2v = vi + hh * k1v, self._accel(xi + hh * k1x, vi + hh * k1v, fi, si)
            k3x, k3v = vi + hh * k2v, self._accel(xi + hh * k2x, vi + hh * k2v, fi, si)
            k4x, k4v = vi + h * k3v, self._accel(xi + h * k3x, vi + h * k3v, fi, si)
            xn = xi + h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x)
            vn = vi + h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
            crossed = si * vn <= 0.0
            if crossed.any():
                # locate v = 0 within the substep and decide stick or move on
                frac = np.where(crossed, vi / np.where(vi - vn == 0, 1.0, vi - vn), 1.0)
                xs = xi + frac * (xn - xi)
                xn = np.where(crossed, xs, xn)
                vn = np.where(crossed, 0.0, vn)
                net_s = fi - p.k * xs
                sticks = crossed & (np.abs(net_s) <= p.fs)
                turns = crossed & ~sticks
                si = np.where(turns, np.sign(net_s), si)
                moving[idx[sticks]] = False
            x[idx], vel[idx], s[idx] = xn, vn, si
        return PhysicalState(x.reshape(shape), vel.reshape(shape), moving.reshape(shape))


# ---------------------------------------------------------------------------------------------
# Two-parameter (S, J) models


def _validate_s_j(model: ChoudhuryValve | KanoValve) -> None:
    """Check S >= 0, 0 <= J <= S and store both as arrays on the frozen dataclass."""
    s = v.non_negative("s", model.s)
    j = v.non_negative("j", model.j)
    if np.any(j > s):
        raise ParameterError("j", f"must not exceed s (j={model.j!r}, s={model.s!r})")
    object.__setattr__(model, "s", s)
    object.__setattr__(model, "j", j)


# Choudhury, Thornhill & Shah (2005)


class ChoudhuryState(NamedTuple):
    x: FloatArray  # valve position
    u_prev: FloatArray  # previous input
    direction: FloatArray  # sign of the last input change (-1, 0, +1)
    stuck: NDArrayBool
    u_stuck: FloatArray  # input when the valve stuck
    stuck_direction: FloatArray  # direction of travel when it stuck


@dataclasses.dataclass(frozen=True)
class ChoudhuryValve:
    """Choudhury, Thornhill & Shah (2005) data-driven model, S (deadband + stickband) and J
    (slip jump), both fractions of span.

    Our reading of the published flowchart: the valve sticks when the input changes
    direction or stops changing, remembering the input u_s at that moment. A stuck valve
    slips when the input has moved away from u_s by more than J while still going the
    way it went before it stuck, or by more than S after a reversal. A slipping or moving
    valve sits at u - d·(S - J)/2, d the direction of travel.
    """

    s: ArrayLike
    j: ArrayLike

    def __post_init__(self) -> None:
        _validate_s_j(self)

    def initial_state(self, u0: ArrayLike) -> ChoudhuryState:
        u = np.array(u0, dtype=np.float64, copy=True)
        z = np.zeros_like(u)
        return ChoudhuryState(u.copy(), u.copy(), z, np.ones(u.shape, bool), u.copy(), z.copy())

    def position(self, state: ChoudhuryState) -> FloatArray:
        return state.x

    def step(self, state: ChoudhuryState, u: ArrayLike) -> ChoudhuryState:
        u = np.broadcast_to(np.asarray(u, dtype=np.float64), state.x.shape)
        d = np.sign(u - state.u_prev)
        newly = ~state.stuck & (d != state.direction)
        stuck = state.stuck | newly
        u_stuck = np.where(newly, state.u_prev, state.u_stuck)
        stuck_dir = np.where(newly, state.direction, state.stuck_direction)
        same_way = (d == stuck_dir) & (d != 0)
        s_, j_ = cast(FloatArray, self.s), cast(FloatArray, self.j)
        gap = np.abs(u - u_stuck)
        slips = stuck & (d != 0) & np.where(same_way, gap > j_, gap > s_)
        free = ~stuck | slips
        x = np.where(free, u - d * (s_ - j_) / 2.0, state.x)
        return ChoudhuryState(x, u.copy(), d, stuck & ~slips, u_stuck, stuck_dir)


# ---------------------------------------------------------------------------------------------
# Kano, Maruta, Kugemoto & Shimizu (2004)


class KanoState(NamedTuple):
    x: FloatArray
    u_prev: FloatArray
    d: FloatArray  # direction the valve would move next (+1/-1)
    stuck: NDArrayBool
    u_stuck: FloatArray


@dataclasses.dataclass(frozen=True)
class KanoValve:
    """Kano et al. (2004) model with S and J (fractions of span).

    Our reading of its flowchart: while moving in direction d, the valve stops when the
    input reverses or holds (u(t) - u(t-1))·d <= 0, remembering u_s = u(t-1) and flipping
    d. Stopped, it moves again when d·(u - u_s) > S (the reversal has overcome deadband
    plus stickband) or when -d·(u - u_s) > J (the input pushes on in the old direction past
    the stickband). Moving, x = u - d·(S - J)/2.
    """

    s: ArrayLike
    j: ArrayLike

    def __post_init__(self) -> None:
        _validate_s_j(self)

    def initial_state(self, u0: ArrayLike) -> KanoState:
        u = np.array(u0, dtype=np.float64, copy=True)
        return KanoState(u.copy(), u.copy(), np.ones_like(u), np.ones(u.shape, bool), u.copy())

    def position(self, state: KanoState) -> FloatArray:
        return state.x

    def step(self, state: KanoState, u: ArrayLike) -> KanoState:
        u = np.broadcast_to(np.asarray(u, dtype=np.float64), state.x.shape)
        d = state.d
        stops = ~state.stuck & ((u - state.u_prev) * d <= 0)
        stuck = state.stuck | stops
        u_stuck = np.where(stops, state.u_prev, state.u_stuck)
        d = np.where(stops, -d, d)
        s_, j_ = cast(FloatArray, self.s), cast(FloatArray, self.j)
        reverse = stuck & (d * (u - u_stuck) > s_)
        onward = stuck & ~reverse & (-d * (u - u_stuck) > j_)
        d = np.where(onward, -d, d)
        free = ~stuck | reverse | onward
        x = np.where(free, u - d * (s_ - j_) / 2.0, state.x)
        return KanoState(x, u.copy(), d, stuck & ~free, u_stuck)
