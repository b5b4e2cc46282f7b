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
(see ``bench/accuracy/real_data.py``), so they are not independent of that data.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.arrays import percentiles
from ..signal.noise import noise_sd
from ..signal.segments import ragged, row_chunks
from .base import Window

__all__ = ["MIN_EPISODES", "Episode", "StickSlip", "detect", "stick_slip"]

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
FIRST_LOOK = 64  # samples: the first chunk of the backward search for a stuck phase's start


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


def _prefix(x: FloatArray) -> FloatArray:
    """Prefix sums of ``x``, 0 first (once per window: both scales read them)."""
    return np.concatenate(([0.0], x.cumsum()))


def _means(c: FloatArray, m: int) -> FloatArray:
    """The centred ``m``-sample running mean (ends held) of the signal whose prefix sums
    are ``c``."""
    v = (c[m:] - c[:-m]) / m
    h = m // 2
    out = np.empty(c.size - 1)
    out[h : h + v.size] = v
    out[:h] = v[0]
    out[h + v.size :] = v[-1]
    return out


def _candidates(a: FloatArray, thr: float, m: int) -> list[int]:
    """Positions of the largest ``a`` above ``thr``, at least ``2 m`` apart (greedy, largest
    first: each pick blocks its neighbourhood).

    Points ``2 m`` or more apart never block each other, so the points above ``thr`` fall
    into independent clusters; a cluster narrower than ``2 m`` (a slip's few samples) gets
    one pick, its first maximum, and only wider ones run the greedy."""
    above = (a >= thr).nonzero()[0]
    if above.size == 0:
        return []
    vals = a[above]
    starts = np.concatenate(([0], (above[1:] - above[:-1] >= 2 * m).nonzero()[0] + 1))
    ends = np.concatenate((starts[1:], [above.size]))
    top = np.maximum.reduceat(vals, starts)
    cluster = np.repeat(np.arange(starts.size), ends - starts)
    at_top = (vals == top[cluster]).nonzero()[0]
    first = at_top[np.concatenate(([True], cluster[at_top[1:]] != cluster[at_top[:-1]]))]
    picked = above[first].tolist()
    for c in (above[ends - 1] - above[starts] >= 2 * m).nonzero()[0].tolist():
        picked.remove(int(above[first[c]]))
        picked.extend(_greedy(above[starts[c] : ends[c]], vals[starts[c] : ends[c]], m))
    return sorted(picked)


def _greedy(at: np.ndarray, vals: FloatArray, m: int) -> list[int]:
    """:func:`_candidates` within one cluster ``at`` (positions, ascending) of values
    ``vals``."""
    picked: list[int] = []
    for i in at[(-vals).argsort(kind="stable")].tolist():
        if all(abs(i - j) >= 2 * m for j in picked):
            picked.append(i)
    return picked


def _still_since_all(ys: FloatArray, end: np.ndarray, level: FloatArray, band: FloatArray
                     ) -> np.ndarray:
    """For each stretch ending at ``end[k]`` (inclusive), the first index from which ``ys``
    stays within ``band[k]`` of ``level[k]``: searched backwards in growing chunks, so a short
    stuck phase costs little in a long window, each chunk one array operation over the
    stretches whose start is still to be found."""
    start = np.zeros(end.size, dtype=np.intp)
    todo = np.arange(end.size)
    hi = end + 1
    width = FIRST_LOOK
    while todo.size:
        pos = hi[todo, None] + np.arange(-width, 0)[None, :]
        away = (pos >= 0) & (np.abs(ys[np.maximum(pos, 0)] - level[todo, None])
                             > band[todo, None])
        found = away.any(axis=1)
        last = width - 1 - away[found, ::-1].argmax(axis=1)
        start[todo[found]] = pos[found, last] + 1
        more = ~found & (pos[:, 0] > 0)
        todo = todo[more]
        hi[todo] -= width
        width *= 4
    return start


def _spreads(x: FloatArray, lo: np.ndarray, hi: np.ndarray) -> FloatArray:
    """The 10-90 % spread (nearest rank) of each ``x[lo[k]:hi[k]]``: rows of a matrix padded
    with +inf, sorted (the ranks stay within each row's own values)."""
    n = hi - lo
    out = np.empty(n.size)
    order = n.argsort(kind="stable")  # similar lengths together: little padding
    for sl in row_chunks(n[order]):
        rows = order[sl]
        idx, mask = ragged(lo[rows], n[rows])
        v = np.sort(np.where(mask, x[idx], np.inf), axis=1)
        k = n[rows] - 1
        r = np.arange(rows.size)
        out[rows] = v[r, np.rint(0.9 * k).astype(np.intp)] - v[r, np.rint(0.1 * k).astype(np.intp)]
    return out


def _turns(us: FloatArray, lo: np.ndarray, end: np.ndarray) -> np.ndarray:
    """For each stretch ``us[lo[k]:end[k] + 1]``, the first index where ``us`` is furthest
    from ``us[end[k]]``."""
    n = end - lo + 1
    out = np.empty(n.size, dtype=np.intp)
    order = n.argsort(kind="stable")
    for sl in row_chunks(n[order]):
        rows = order[sl]
        idx, mask = ragged(lo[rows], n[rows])
        far = np.where(mask, np.abs(us[end[rows], None] - us[idx]), -1.0)
        out[rows] = lo[rows] + far.argmax(axis=1)
    return out


def stick_slip(op: FloatArray, pv: FloatArray, *, noise: tuple[float, float] | None = None,
               pv_range: tuple[float, float] | None = None) -> StickSlip:
    """Find stick-slip episodes in a window of OP and PV (equal-length, finite); ``noise``:
    the white-noise SDs of OP and PV (:func:`~stiction.signal.noise.noise_sd`), ``pv_range``:
    PV's 2nd and 98th percentiles, when the caller has them."""
    found: list[Episode] = []
    if op.size < 5 * M + 2:
        return StickSlip((), True)
    p2, p98 = pv_range or percentiles(pv, (2.0, 98.0))
    sd_op, sd_pv = noise or (noise_sd(op), noise_sd(pv))
    sums = (_prefix(op), _prefix(pv))
    for m in SCALES:
        taken = np.array([f.at for f in found])
        new = _episodes(sums, m, (sd_pv, sd_op, float(p98 - p2)))
        if taken.size and new:
            at = np.array([e.at for e in new])
            clash = (np.abs(taken[None, :] - at[:, None]) < 2 * m).any(axis=1)
            new = [e for e, c in zip(new, clash.tolist(), strict=True) if not c]
        found.extend(new)
    found.sort(key=lambda e: e.at)
    signs = {math.copysign(1.0, e.jump) * math.copysign(1.0, e.op_travel) for e in found}
    return StickSlip(tuple(found), len(signs) <= 1)


def _episodes(sums: tuple[FloatArray, FloatArray], m: int, noise: tuple[float, float, float]
              ) -> list[Episode]:
    """The episodes seen with ``m``-sample means on either side of the slip; ``sums``: the
    prefix sums of OP and PV (:func:`_prefix`); ``noise``: the noise SDs of PV and OP and
    PV's 2-98 % range. Every candidate slip is checked at once (arrays over the
    candidates)."""
    cu, cy = sums
    n = cu.size - 1
    if n < 5 * m + 2:  # the means before and after, a stuck phase of 3 m
        return []
    sd_y, sd_u, rng = noise
    thr = max(JUMP_NOISE * sd_y * math.sqrt(2.0 / m), JUMP_RANGE_FRACTION * rng)
    if thr <= 0:
        return []
    ys = _means(cy, m)
    # at sample t = m + i: mean after - mean before
    dy = (cy[2 * m :] - 2.0 * cy[m : n - m + 1] + cy[: n - 2 * m + 1]) / m
    cand = np.asarray(_candidates(np.abs(dy), thr, m), dtype=np.intp)
    if cand.size == 0:
        return []
    us = _means(cu, m)
    at = cand + m
    d = dy[cand]
    step = (cu[at + m] - 2.0 * cu[at] + cu[at - m]) / m
    pre = (cy[at] - cy[at - m]) / m
    # the stuck phase: back from the slip while PV stays near its pre-slip level
    end = at - m
    start = _still_since_all(ys, end, pre, STUCK_BAND * np.abs(d))
    # the force was built since OP's last turn: its extreme (furthest from the pre-slip
    # OP) while PV stood still
    lo = _turns(us, np.minimum(start + m // 2, end), end)
    stuck = end - lo
    travel = us[end] - us[lo]
    ok = ((stuck >= 3 * m) & (np.abs(travel) >= OP_NOISE * sd_u)
          & (np.abs(step) < KICK_RATIO * np.abs(travel))
          & ~((np.copysign(1.0, step) == np.copysign(1.0, travel))
              & (np.abs(step) >= SAME_WAY_KICK * np.abs(travel))))
    # OP monotone over the stuck phase (m-sample means), then PV still over it
    k = ok.nonzero()[0]
    steps = (stuck[k] // m).astype(np.intp)  # path points us[lo], us[lo + m], ... after the first
    path = lo[k, None] + m * np.arange(int(np.maximum.reduce(steps, initial=0)) + 1)[None, :]
    up = us[np.minimum(path, n - 1)]
    hop = np.where(np.arange(path.shape[1] - 1)[None, :] < steps[:, None],
                   np.abs(up[:, 1:] - up[:, :-1]), 0.0)
    tv = np.add.reduce(hop, axis=1)
    k = k[(tv > 0) & (np.abs(travel[k]) >= MONOTONE * tv)]
    k = k[_spreads(ys, lo[k], end[k] + 1) <= STILL_SPREAD * np.abs(d[k])]
    return [Episode(*fields) for fields in zip(at[k].tolist(), d[k].tolist(), travel[k].tolist(),
                                               step[k].tolist(), stuck[k].tolist(), strict=True)]


MIN_EPISODES = 2
"""Stick-slip episodes (with one gain sign) a window needs before the test votes: one
episode alone made two of three false calls on outside loops (a fan without a valve, a loop
moved by a disturbance)."""


def detect(w: Window) -> Evidence:
    """``stick_slip``: stick-slip episodes without a cycle, +1 from ``MIN_EPISODES``
    episodes with one gain sign; never -1."""
    levels = w.levels[1]
    return _evidence(stick_slip(w.op, w.pv, noise=w.noise, pv_range=(levels[0], levels[2])))


def _evidence(ss: StickSlip) -> Evidence:
    if ss.detected and len(ss.episodes) < MIN_EPISODES:
        e = ss.episodes[0]
        return Evidence("stick_slip", 1.0, 0, f"one stick-slip episode (OP ramped "
                        f"{e.op_travel:+.3g} with PV still, then PV jumped {e.jump:+.3g}): a "
                        "hint, not evidence alone (a load step can do the same once)")
    if not ss.detected:
        note = ("stick-slip episodes with opposite gain signs" if ss.episodes
                else "no stick-slip episode")
        return Evidence("stick_slip", float(len(ss.episodes)), 0, note)
    e = max(ss.episodes, key=lambda ep: abs(ep.jump))
    count = len(ss.episodes)
    return Evidence("stick_slip", float(count), 1,
                    f"{count} stick-slip episode{'s' if count > 1 else ''}: OP ramped "
                    f"(largest {e.op_travel:+.3g} over {e.stuck} samples) with PV still, "
                    f"then PV jumped ({e.jump:+.3g}) and OP did not")
