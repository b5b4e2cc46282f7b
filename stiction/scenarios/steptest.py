"""Simulated step tests: a loop held in manual while OP plays a sequence, and what its valve
truly does.

:func:`simulate_step_test` runs ``n`` loops at once (a :class:`~stiction.models.simulate.
LoopBank` in manual) through one OP sequence: each level of ``levels`` (% of span) held
``hold`` samples. It returns OP, PV, the valve position VP (optionally with noise, as a
positioner reports it) and, per loop, the valve's own dead band, resolution and slip in
this test, read from the valve model itself, never from the recordings:

* at the end of every hold in which the valve moved, the OP travel that would move it
  again, onward (the *resolution*: no reversal) and back (the *dead band*: after a
  reversal), found by bisection on one jump of OP from the rest state (for every model here
  a jump moves the valve exactly when a ramp to the same OP would); each counted where the
  test measured it (the way back where the valve's next move was back, the way on where
  it went on);
* the *slip*: how far the valve jumped when it broke free after at least one step that
  did not move it, in the direction it went before.

Each is the median over the test (for He's model with K > 1 they vary a little with the
size of the last jump). Values in % of span.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray
from ..models.simulate import LoopBank, LoopParams

__all__ = ["StepTestRun", "simulate_step_test", "travel_to_move"]


@dataclasses.dataclass(frozen=True)
class StepTestRun:
    """``n`` simulated step tests: rows are loops, columns samples (``t`` in s)."""

    t: FloatArray
    op: FloatArray  # % of span
    pv: FloatArray  # process units
    vp: FloatArray  # % of span, with the position noise
    deadband: FloatArray  # per loop, % of span (NaN: the valve never moved)
    resolution: FloatArray
    slip: FloatArray  # 0 when the valve never stuck between moves


def travel_to_move(valve: Any, state: Any, u: FloatArray, direction: FloatArray,
                   *, most: float = 1.0, tol: float = 1e-6) -> FloatArray:
    """Per loop, the OP travel (fraction of span) from ``u`` in ``direction`` that moves the
    valve out of ``state`` in one jump (bisection to ``tol``; ``most`` if none does)."""
    x0 = valve.position(state)
    lo, hi = np.zeros_like(u), np.full_like(u, most)

    def moves(travel: FloatArray) -> NDArray[np.bool_]:
        moved: NDArray[np.bool_] = np.abs(
            valve.position(valve.step(state, u + direction * travel)) - x0) > 1e-12
        return moved

    never = np.logical_not(moves(hi))
    while float(np.max(hi - lo)) > tol:
        mid = (lo + hi) / 2.0
        m = moves(mid)
        hi, lo = np.where(m, mid, hi), np.where(m, lo, mid)
    out: FloatArray = np.where(never, most, hi)
    return out


def simulate_step_test(valve: Any, levels: ArrayLike, *, hold: int, ts: float = 1.0,
                       n: int = 1, kp: ArrayLike = 1.0, tau: ArrayLike = 10.0,
                       theta: ArrayLike = 0.0, integrating: ArrayLike = False,
                       noise_sd: ArrayLike = 0.0, position_noise_sd: float = 0.0,
                       seed: int = 0, ramp: int = 1) -> StepTestRun:
    """``n`` loops (parameters scalars or arrays of ``n``; ``valve``'s likewise) step-tested
    with ``levels`` (% of span, the first the operating point), ``hold`` samples each.
    ``ramp``: samples each step takes (OP moves in equal parts, as an operator ramping
    it by hand; 1, the default, an instant step); the level is reached at the ramp's last
    sample, so a hold of ``hold`` samples includes it."""
    if int(ramp) != ramp or not 1 <= ramp <= hold:
        raise ParameterError("ramp", f"must be a whole number of samples from 1 to hold "
                             f"({hold}), was {ramp!r}")
    lv = v.finite("levels", levels).reshape(-1)
    params = LoopParams(kp=kp, tau=tau, theta=theta, integrating=integrating,
                        x0=float(lv[0]) / 100.0, noise_sd=noise_sd, kc=0.0)
    bank = LoopBank(n, params, valve, ts=ts, seed=seed)
    rows = lv.size * int(hold)
    op, pv, vp = (np.empty((n, rows)) for _ in range(3))
    ends: list[Any] = []  # the valve state at the end of each hold
    for i, level in enumerate(lv):
        before = lv[max(i - 1, 0)]
        for j in range(int(hold)):
            u = level if j + 1 >= ramp else before + (level - before) * (j + 1) / ramp
            out = bank.step(manual=np.full(n, u / 100.0))
            k = i * int(hold) + j
            op[:, k], pv[:, k], vp[:, k] = out.op, out.pv, out.vp
        ends.append(bank.valve_state)
    x_end = vp[:, int(hold) - 1::int(hold)] / 100.0  # per loop and hold
    truth = _truth(valve, ends, lv / 100.0, x_end)
    rng = np.random.default_rng(seed + 1)
    noisy = vp + rng.standard_normal(vp.shape) * position_noise_sd
    t = np.arange(rows) * ts
    return StepTestRun(t.astype(np.float64), op, pv, noisy.astype(np.float64), *truth)


def _truth(valve: Any, ends: list[Any], u: FloatArray, x: FloatArray
           ) -> tuple[FloatArray, FloatArray, FloatArray]:
    n, holds = x.shape
    moved = np.zeros((n, holds), bool)
    moved[:, 1:] = np.abs(np.diff(x, axis=1)) > 1e-9
    onward, back = np.full((n, holds), np.nan), np.full((n, holds), np.nan)
    d = np.zeros((n, holds))
    d[:, 1:] = np.sign(np.diff(x, axis=1))
    slips = np.full((n, holds), np.nan)
    direction = np.zeros(n)  # of each loop's last move
    for k in range(1, holds):
        m = moved[:, k]
        if m.any():
            uk = np.full(n, u[k])
            dk = np.where(m, d[:, k], 1.0)
            onward[:, k] = np.where(m, travel_to_move(valve, ends[k], uk, dk), np.nan)
            back[:, k] = np.where(m, travel_to_move(valve, ends[k], uk, -dk), np.nan)
            broke = m & ~moved[:, k - 1] & (d[:, k] == direction)
            slips[:, k] = np.where(broke, np.abs(x[:, k] - x[:, k - 1]), np.nan)
        direction = np.where(m, d[:, k], direction)
    # each threshold where the test then measured it: the way back at moves the next move
    # reversed, the way on at moves the next move continued
    nxt, step = _next_move(moved, d, np.abs(np.diff(u, prepend=u[0])))
    back = np.where(nxt == -d, back, np.nan)
    onward = np.where(nxt == d, onward, np.nan)
    with warnings.catch_warnings():  # a valve that never moved: NaN, said so
        warnings.simplefilter("ignore", RuntimeWarning)
        slip = np.where(np.isfinite(slips).any(axis=1), np.nanmedian(slips, axis=1), 0.0)
    return (100.0 * _weighted_median(back, step), 100.0 * _weighted_median(onward, step),
            100.0 * slip)


def _next_move(moved: np.ndarray, d: FloatArray, steps: FloatArray
               ) -> tuple[FloatArray, FloatArray]:
    """Per loop and hold, the direction of the valve's next move after it (0: none) and
    the OP step that made it."""
    out, size = np.zeros(d.shape), np.ones(d.shape)
    following, following_step = np.zeros(d.shape[0]), np.ones(d.shape[0])
    for k in range(d.shape[1] - 1, -1, -1):
        out[:, k], size[:, k] = following, following_step
        following = np.where(moved[:, k], d[:, k], following)
        following_step = np.where(moved[:, k], steps[k], following_step)
    return out, size


def _weighted_median(values: FloatArray, step: FloatArray) -> FloatArray:
    """Per loop (row), the median of the finite values, each weighted by 1 / the OP step
    that measured it: as the analysis weighs a move's bracket (:mod:`stiction.valvetest.
    bands`), so a valve whose thresholds vary (He's with K > 1) is judged on the same mix."""
    out = np.full(values.shape[0], np.nan)
    for i, (row, w) in enumerate(zip(values, step, strict=True)):
        good = np.isfinite(row)
        if good.any():
            order = np.argsort(row[good])
            cum = np.cumsum(1.0 / np.maximum(w[good][order], 1e-12))
            out[i] = row[good][order][int(np.searchsorted(cum, cum[-1] / 2.0))]
    return out
