"""Stick-slip episodes: stiction seen without a limit cycle.

He et al.'s (2007) curve fitting needs a regular oscillation. A sticky valve in a loop that
is not cycling (set-point moves, slow load changes, a window shorter than the slip period)
shows instead isolated stick-slip episodes, the pattern Kano et al. (2004) look for in the
OP-PV plot: the controller output ramps (integral action on a persistent error) while the
valve, and so PV, stays put; then the valve breaks away and PV jumps; the controller,
seeing the jump it did not cause, turns back. Per candidate jump we check exactly that:

1. **Slip.** PV changes fast: the difference of the means of the ``M`` samples after and
   before a point is at least ``JUMP_RANGE_FRACTION`` of PV's (2-98 %) range and at least
   ``JUMP_NOISE`` standard errors of that difference under white measurement noise.
2. **Stuck before.** Going back from the slip, PV (``M``-sample running mean) stays within
   ``STUCK_BAND`` of the jump of its pre-slip level for at least ``MIN_STUCK`` samples.
3. **OP built the force.** Over that stuck phase OP travelled monotonically (net change at
   least ``MONOTONE`` of its total variation, on ``M``-sample means) and by at least
   ``OP_NOISE`` OP noise SDs: the valve stood still while its input moved.
4. **OP did not cause the jump.** Across the slip, OP moved less than its travel during the
   stuck phase, and not in the same direction as that travel by more than a quarter of it:
   a PV step that comes with an equal or larger OP step is a response (a set-point change,
   a proportional kick), not a slip. (Healthy loops whose PV follows OP fail here.)
5. **One process gain.** The apparent gain sign, sign(PV jump) x sign(OP travel), is the
   same for every accepted episode of the window: a real valve has one gain sign.

Thresholds are physical fractions chosen once; ``OP_NOISE``, ``MONOTONE`` and the OP-step
rule were checked against the plant records of ``../shared/data/plant-stictiongpt``
(see ``bench/plant_data.py``), so they are not independent of that data.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._detect import noise_sd
from ._validate import FloatArray

__all__ = ["Episode", "StickSlip", "stick_slip"]

M = 5
JUMP_RANGE_FRACTION = 0.3
JUMP_NOISE = 8.0
STUCK_BAND = 0.5
MIN_STUCK = 3 * M
MONOTONE = 0.7
OP_NOISE = 10.0
SAME_WAY_KICK = 0.25
KICK_RATIO = 1.0


@dataclasses.dataclass(frozen=True)
class Episode:
    """One stick-slip episode: PV jumps by ``jump`` at sample ``at`` after OP travelled
    ``op_travel`` over the ``stuck`` samples before, with PV still."""

    at: int
    jump: float
    op_travel: float
    op_step: float
    stuck: int


@dataclasses.dataclass(frozen=True)
class StickSlip:
    episodes: tuple[Episode, ...]
    consistent: bool  # every episode has the same apparent gain sign

    @property
    def detected(self) -> bool:
        return bool(self.episodes) and self.consistent


def _means(x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Prefix sums of ``x`` and its centred ``M``-sample running mean (ends held)."""
    c = np.concatenate(([0.0], np.cumsum(x)))
    v = (c[M:] - c[:-M]) / M
    h = M // 2
    out = np.empty(x.size)
    out[h : h + v.size] = v
    out[:h] = v[0]
    out[h + v.size :] = v[-1]
    return c, out


def _candidates(a: FloatArray, thr: float) -> list[int]:
    """Positions of the largest ``a`` above ``thr``, at least ``2 M`` apart."""
    picked: list[int] = []
    for i in np.argsort(-a).tolist():
        if a[i] < thr:
            break
        if all(abs(i - j) >= 2 * M for j in picked):
            picked.append(i)
    return sorted(picked)


def stick_slip(op: FloatArray, pv: FloatArray) -> StickSlip:
    """Find stick-slip episodes in a window of OP and PV (equal-length, finite)."""
    n = op.size
    if n < 2 * M + MIN_STUCK + 2:
        return StickSlip((), True)
    cy, ys = _means(pv)
    cu, us = _means(op)
    t = np.arange(M, n - M + 1)
    dy = (cy[t + M] - 2.0 * cy[t] + cy[t - M]) / M  # mean after - mean before
    du = (cu[t + M] - 2.0 * cu[t] + cu[t - M]) / M
    p2, p98 = np.percentile(pv, [2, 98])
    rng = float(p98 - p2)
    thr = max(JUMP_NOISE * noise_sd(pv) * math.sqrt(2.0 / M), JUMP_RANGE_FRACTION * rng)
    if thr <= 0:
        return StickSlip((), True)
    sd_u = noise_sd(op)
    found: list[Episode] = []
    for i in _candidates(np.abs(dy), thr):
        at = int(t[i])
        d = float(dy[i])
        pre = float((cy[at] - cy[at - M]) / M)
        # the stuck phase: back from the slip while PV stays near its pre-slip level
        away = np.flatnonzero(np.abs(ys[: at - M + 1] - pre) > STUCK_BAND * abs(d))
        start = int(away[-1]) + 1 if away.size else 0
        stuck = at - M - start
        if stuck < MIN_STUCK:
            continue
        lo = min(start + M // 2, at - M)
        travel = float(us[at - M] - us[lo])
        path = us[lo : at - M + 1 : M]
        tv = float(np.sum(np.abs(np.diff(path)))) if path.size > 1 else 0.0
        if tv <= 0 or abs(travel) < MONOTONE * tv or abs(travel) < OP_NOISE * sd_u:
            continue
        step = float(du[i])
        if abs(step) >= KICK_RATIO * abs(travel):
            continue
        if math.copysign(1.0, step) == math.copysign(1.0, travel) \
                and abs(step) >= SAME_WAY_KICK * abs(travel):
            continue
        found.append(Episode(at, d, travel, step, stuck))
    signs = {math.copysign(1.0, e.jump) * math.copysign(1.0, e.op_travel) for e in found}
    return StickSlip(tuple(found), len(signs) <= 1)
