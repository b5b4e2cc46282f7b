"""Stick-slip episodes: stiction seen without a limit cycle.

He et al.'s (2007) curve fitting needs a regular oscillation. A sticky valve in a loop that
is not cycling (set-point moves, slow load changes, a window shorter than the slip period)
shows instead isolated stick-slip episodes, the pattern Kano et al. (2004) look for in the
OP-PV plot: the controller output ramps (integral action on a persistent error) while the
valve, and so PV, stays put; then the valve breaks away and PV jumps; the controller,
seeing the jump it did not cause, turns back. Per candidate jump we check exactly that:

The search runs on two scales, ``m = M`` and ``2 M`` samples (``SCALES``): with slow
sampling or a valve that slips in two steps, the slip spans more than ``M`` samples and the
``M``-sample means see only part of it. Episodes found on both scales count once.

1. **Slip.** PV changes fast: the difference of the means of the ``m`` samples after and
   before a point is at least ``JUMP_RANGE_FRACTION`` of PV's (2-98 %) range and at least
   ``JUMP_NOISE`` standard errors of that difference under white measurement noise.
2. **Stuck before.** Going back from the slip, PV (``m``-sample running mean) stays within
   ``STUCK_BAND`` of the jump of its pre-slip level. Within that still stretch, the force
   that broke the valve was built since OP's last turn: the stuck phase starts where OP was
   furthest from its pre-slip value, and must last at least ``3 m`` samples. Over it PV
   must be still, not wandering inside the band: the 10-90 % spread of its ``m``-sample
   means at most ``STILL_SPREAD`` of the jump. (White noise alone on a stuck valve gives at
   most 0.23 at the smallest jump the slip test accepts; the plant's stick-slip records
   0.07-0.42; a healthy loop wandering under a random load, the false alarms this stops,
   0.46-0.60.)
3. **OP built the force.** Over that stuck phase OP travelled monotonically (net change at
   least ``MONOTONE`` of its total variation, on ``m``-sample means) and by at least
   ``OP_NOISE`` OP noise SDs: the valve stood still while its input moved.
4. **OP did not cause the jump.** Across the slip, OP moved less than its travel during the
   stuck phase, and not in the same direction as that travel by more than a quarter of it:
   a PV step that comes with an equal or larger OP step is a response (a set-point change,
   a proportional kick), not a slip. (Healthy loops whose PV follows OP fail here.)
5. **One process gain.** The apparent gain sign, sign(PV jump) x sign(OP travel), is the
   same for every accepted episode of the window: a real valve has one gain sign.

Thresholds are physical fractions chosen once; ``OP_NOISE``, ``MONOTONE``, the OP-step
rule, the second scale and the stuck phase from OP's turn were checked against the plant
records of ``../shared/data/plant-stictiongpt``
(see ``bench/real_data.py``), so they are not independent of that data.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._detect import noise_sd
from ._validate import FloatArray

__all__ = ["Episode", "StickSlip", "stick_slip"]

M = 5
SCALES = (M, 2 * M)
JUMP_RANGE_FRACTION = 0.3
JUMP_NOISE = 8.0
STUCK_BAND = 0.5
STILL_SPREAD = 0.45
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


def _means(x: FloatArray, m: int) -> tuple[FloatArray, FloatArray]:
    """Prefix sums of ``x`` and its centred ``m``-sample running mean (ends held)."""
    c = np.concatenate(([0.0], np.cumsum(x)))
    v = (c[m:] - c[:-m]) / m
    h = m // 2
    out = np.empty(x.size)
    out[h : h + v.size] = v
    out[:h] = v[0]
    out[h + v.size :] = v[-1]
    return c, out


def _candidates(a: FloatArray, thr: float, m: int) -> list[int]:
    """Positions of the largest ``a`` above ``thr``, at least ``2 m`` apart (greedy, largest
    first: each pick blocks its neighbourhood)."""
    above = np.flatnonzero(a >= thr)
    blocked = np.zeros(a.size, dtype=bool)
    picked: list[int] = []
    for i in above[np.argsort(-a[above], kind="stable")].tolist():
        if not blocked[i]:
            picked.append(i)
            blocked[max(0, i - 2 * m + 1) : i + 2 * m] = True
    return sorted(picked)


def _still_since(ys: FloatArray, end: int, level: float, band: float) -> int:
    """First index of the stretch ending at ``end`` (inclusive) in which ``ys`` stays within
    ``band`` of ``level``; searched backwards in growing chunks, so a short stuck phase
    costs little in a long window."""
    hi = end + 1
    width = 64
    while hi > 0:
        lo = max(0, hi - width)
        away = np.flatnonzero(np.abs(ys[lo:hi] - level) > band)
        if away.size:
            return lo + int(away[-1]) + 1
        hi, width = lo, 4 * width
    return 0


def _spread(x: FloatArray) -> float:
    """The 10-90 % spread of ``x`` (nearest-rank; cheaper than ``np.percentile``)."""
    k = x.size - 1
    lo, hi = round(0.1 * k), round(0.9 * k)
    part = np.partition(x, (lo, hi))
    return float(part[hi] - part[lo])


def stick_slip(op: FloatArray, pv: FloatArray) -> StickSlip:
    """Find stick-slip episodes in a window of OP and PV (equal-length, finite)."""
    found: list[Episode] = []
    if op.size < 5 * M + 2:
        return StickSlip((), True)
    p2, p98 = np.percentile(pv, [2, 98])
    noise = (noise_sd(pv), noise_sd(op), float(p98 - p2))
    for m in SCALES:
        taken = np.array([f.at for f in found])
        for e in _episodes(op, pv, m, noise):
            if not np.any(np.abs(taken - e.at) < 2 * m):
                found.append(e)
    found.sort(key=lambda e: e.at)
    signs = {math.copysign(1.0, e.jump) * math.copysign(1.0, e.op_travel) for e in found}
    return StickSlip(tuple(found), len(signs) <= 1)


def _episodes(op: FloatArray, pv: FloatArray, m: int, noise: tuple[float, float, float]
              ) -> list[Episode]:
    """The episodes seen with ``m``-sample means on either side of the slip; ``noise``: the
    noise SDs of PV and OP and PV's 2-98 % range."""
    n = op.size
    if n < 5 * m + 2:  # the means before and after, a stuck phase of 3 m
        return []
    cy, ys = _means(pv, m)
    cu, us = _means(op, m)
    t = np.arange(m, n - m + 1)
    dy = (cy[t + m] - 2.0 * cy[t] + cy[t - m]) / m  # mean after - mean before
    du = (cu[t + m] - 2.0 * cu[t] + cu[t - m]) / m
    sd_y, sd_u, rng = noise
    thr = max(JUMP_NOISE * sd_y * math.sqrt(2.0 / m), JUMP_RANGE_FRACTION * rng)
    if thr <= 0:
        return []
    found: list[Episode] = []
    for i in _candidates(np.abs(dy), thr, m):
        at = int(t[i])
        d = float(dy[i])
        pre = float((cy[at] - cy[at - m]) / m)
        # the stuck phase: back from the slip while PV stays near its pre-slip level
        start = _still_since(ys, at - m, pre, STUCK_BAND * abs(d))
        # the force was built since OP's last turn: its extreme (furthest from the pre-slip
        # OP) while PV stood still
        end = at - m
        lo = min(start + m // 2, end)
        lo += int(np.argmax(np.abs(us[end] - us[lo : end + 1])))
        stuck = end - lo
        if stuck < 3 * m:
            continue
        # the cheap scalar checks first, the still-PV spread (a partition) last
        travel = float(us[end] - us[lo])
        step = float(du[i])
        if abs(travel) < OP_NOISE * sd_u or abs(step) >= KICK_RATIO * abs(travel):
            continue
        if math.copysign(1.0, step) == math.copysign(1.0, travel) \
                and abs(step) >= SAME_WAY_KICK * abs(travel):
            continue
        path = us[lo : end + 1 : m]
        tv = float(np.sum(np.abs(np.diff(path)))) if path.size > 1 else 0.0
        if tv <= 0 or abs(travel) < MONOTONE * tv:
            continue
        if _spread(ys[lo : end + 1]) > STILL_SPREAD * abs(d):
            continue
        found.append(Episode(at, d, travel, step, stuck))
    return found
