"""Closed-loop simulation: PI controller -> valve model -> process with dead time.

Everything is vectorised over loops: a :class:`LoopBank` holds the state of ``n``
independent loops as arrays and :meth:`LoopBank.step` advances all of them one sample
(zero-order hold at ``ts``) with a fixed number of numpy operations, independent of ``n``.

Units. OP and VP are fractions of the valve span inside the bank and percent of span in
every output. PV is in process units: ``pv = pv0 + 100·y`` where ``y`` is the process
response to the valve position's deviation from its operating point ``x0``; with the
default ``kp = 1`` a 1 % valve move ends as a 1-unit PV move, so ``kp`` is also the gain in
PV units per % OP that :func:`stiction.analyze` takes. The setpoint is in PV units.

Discretisation. FOPTD  G(s) = Kp·exp(-θs)/(τs+1) and integrating G(s) = Kp·exp(-θs)/s are
discretised exactly for a piecewise-constant input, including a fractional dead time
θ = (d + f)·ts: the input of two samples back acts for the first f·ts of the interval.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray
from .valves import ValveModel

__all__ = ["LoopBank", "LoopParams", "StepOutput"]


@dataclasses.dataclass(frozen=True)
class LoopParams:
    """Parameters of ``n`` loops; every field is a scalar or an array broadcastable to n.

    ``integrating`` selects Kp·exp(-θs)/s instead of FOPTD (``tau`` is then unused).
    ``dist_amp`` (fraction of span, at the process input) and ``dist_period`` (s) add a
    sinusoidal load disturbance; ``dist_period = 0`` turns it off. ``load_sd`` (fraction of
    span) adds a random load: white noise through a first-order filter of time constant
    ``load_tau`` (s), scaled so its standard deviation is ``load_sd``. ``noise_sd`` is the
    standard deviation of white measurement noise on PV, in PV units.
    """

    kc: ArrayLike = 1.0
    ti: ArrayLike = 60.0
    kp: ArrayLike = 1.0
    tau: ArrayLike = 60.0
    theta: ArrayLike = 0.0
    integrating: ArrayLike = False
    x0: ArrayLike = 0.5
    pv0: ArrayLike = 50.0
    op_lo: ArrayLike = 0.0
    op_hi: ArrayLike = 1.0
    noise_sd: ArrayLike = 0.0
    dist_amp: ArrayLike = 0.0
    dist_period: ArrayLike = 0.0
    dist_phase: ArrayLike = 0.0
    load_sd: ArrayLike = 0.0
    load_tau: ArrayLike = 30.0


class StepOutput(NamedTuple):
    """One sample of every loop: OP and VP in % of span, PV and SP in process units."""

    op: FloatArray
    pv: FloatArray
    vp: FloatArray
    sp: FloatArray


class LoopBank:
    """``n`` independent PI loops with one valve model (its parameters may differ per loop).

    Deterministic for a given ``seed``. ``valve`` is any :class:`~stiction.valves.ValveModel`
    whose parameter arrays broadcast to ``n``.
    """

    def __init__(
        self,
        n: int,
        params: LoopParams,
        valve: ValveModel[Any],
        *,
        ts: float = 1.0,
        seed: int | None = 0,
    ) -> None:
        if int(n) != n or n < 1:
            raise ParameterError("n", f"must be a positive integer, was {n!r}")
        self.n = int(n)
        self.ts = v.positive_scalar("ts", ts)
        p = params

        def arr(name: str, value: ArrayLike) -> FloatArray:
            try:
                return np.broadcast_to(np.asarray(value, dtype=np.float64), (self.n,)).copy()
            except ValueError as exc:
                raise ParameterError(name, f"must broadcast to {self.n} loops") from exc

        self.kc = arr("kc", v.finite("kc", p.kc))
        self.ti = arr("ti", v.positive("ti", p.ti))
        self.kp = arr("kp", v.finite("kp", p.kp))
        self.theta = arr("theta", v.non_negative("theta", p.theta))
        self.integrating = np.broadcast_to(np.asarray(p.integrating, dtype=bool), (self.n,)).copy()
        tau = arr("tau", v.as_float_array("tau", p.tau))
        if np.any(~self.integrating & ~(tau > 0)):
            raise ParameterError("tau", "must be > 0 for self-regulating loops")
        self.tau = np.where(self.integrating, 1.0, tau)
        self.x0 = arr("x0", v.finite("x0", p.x0))
        self.pv0 = arr("pv0", v.finite("pv0", p.pv0))
        self.op_lo = arr("op_lo", v.finite("op_lo", p.op_lo))
        self.op_hi = arr("op_hi", v.finite("op_hi", p.op_hi))
        if np.any(self.op_hi <= self.op_lo):
            raise ParameterError("op_hi", "must exceed op_lo")
        self.noise_sd = arr("noise_sd", v.non_negative("noise_sd", p.noise_sd))
        self.dist_amp = arr("dist_amp", v.finite("dist_amp", p.dist_amp))
        self.dist_period = arr("dist_period", v.non_negative("dist_period", p.dist_period))
        self.dist_phase = arr("dist_phase", v.finite("dist_phase", p.dist_phase))
        self.load_sd = arr("load_sd", v.non_negative("load_sd", p.load_sd))
        load_tau = arr("load_tau", v.positive("load_tau", p.load_tau))
        self._load_c = np.exp(-self.ts / load_tau)
        self._load = np.zeros(self.n)
        self.valve = valve
        self._rng = np.random.default_rng(seed)

        # exact ZOH discretisation with fractional dead time theta = (d + f) ts
        ts_ = self.ts
        delay = self.theta / ts_
        self._d = np.floor(delay + 1e-12).astype(np.intp)
        f = delay - self._d
        a = np.exp(-ts_ / self.tau)
        a1f = np.exp(-(1.0 - f) * ts_ / self.tau)
        self._a = np.where(self.integrating, 1.0, a)
        self._b1 = np.where(self.integrating, self.kp * (1.0 - f) * ts_, self.kp * (1.0 - a1f))
        self._b2 = np.where(
            self.integrating, self.kp * f * ts_, self.kp * a1f * (1.0 - np.exp(-f * ts_ / self.tau))
        )
        self._hlen = int(self._d.max()) + 2
        self._hist = np.zeros((self.n, self._hlen))  # past (vp - x0 + load), ring buffer
        self._ptr = 0
        self._rows = np.arange(self.n)
        self.k = 0  # samples taken
        self.y = np.zeros(self.n)  # process output deviation, fraction of span
        self.integral = np.zeros(self.n)
        self.valve_state = valve.initial_state(self.x0.copy())
        self.sp = self.pv0.copy()

    @property
    def t(self) -> float:
        """Time of the next sample, s."""
        return self.k * self.ts

    def step(self, sp: ArrayLike | None = None, load: ArrayLike | None = None,
             manual: ArrayLike | None = None) -> StepOutput:
        """Advance every loop one sample; ``sp`` (PV units) replaces the setpoints if given;
        ``load`` (fraction of span, per loop) is added at the process input for this sample,
        on top of the sinusoidal and random loads of :class:`LoopParams` (for load shapes
        those do not cover: random walks, steps, square waves, another loop's output).
        ``manual`` (fraction of span, per loop; NaN: that loop stays in automatic) holds
        loops in manual at that controller output, as an operator or a step test does; the
        integral tracks it, so automatic resumes without a bump."""
        if sp is not None:
            self.sp = np.broadcast_to(np.asarray(sp, dtype=np.float64), (self.n,)).copy()
        extra = None if load is None else np.broadcast_to(
            np.asarray(load, dtype=np.float64), (self.n,))
        t = self.k * self.ts
        noise = self._rng.standard_normal(self.n) * self.noise_sd
        if np.any(self.load_sd > 0):
            c = self._load_c
            w = self._rng.standard_normal(self.n)
            self._load = c * self._load + np.sqrt(1.0 - c * c) * self.load_sd * w
        pv = self.pv0 + 100.0 * self.y + noise
        # positional PI with conditional integration (anti-windup) and output clamp
        e = (self.sp - pv) / 100.0
        integral = self.integral + e * self.ts / self.ti
        raw = self.x0 + self.kc * (e + integral)
        op = np.clip(raw, self.op_lo, self.op_hi)
        saturated = raw != op
        winding_up = saturated & (np.sign(e) == np.sign(raw - op))
        self.integral = np.where(winding_up, self.integral, integral)
        if manual is not None:
            held = np.broadcast_to(np.asarray(manual, dtype=np.float64), (self.n,))
            in_manual = ~np.isnan(held)
            op = np.clip(np.where(in_manual, held, op), self.op_lo, self.op_hi)
            tracks = in_manual & (self.kc != 0)  # bumpless transfer back to automatic
            self.integral = np.where(
                tracks, (op - self.x0) / np.where(tracks, self.kc, 1.0) - e, self.integral)
        self.valve_state = self.valve.step(self.valve_state, op)
        vp = self.valve.position(self.valve_state)
        load = np.where(
            self.dist_period > 0,
            self.dist_amp
            * np.sin(2 * np.pi * t / np.where(self.dist_period > 0, self.dist_period, 1.0)
                     + self.dist_phase),
            0.0,
        )
        self._ptr = (self._ptr + 1) % self._hlen
        if extra is not None:
            load = load + extra
        self._hist[:, self._ptr] = vp - self.x0 + load + self._load
        u_d = self._hist[self._rows, (self._ptr - self._d) % self._hlen]
        u_d1 = self._hist[self._rows, (self._ptr - self._d - 1) % self._hlen]
        self.y = self._a * self.y + self._b1 * u_d + self._b2 * u_d1
        self.k += 1
        return StepOutput(op * 100.0, pv, vp * 100.0, self.sp.copy())
