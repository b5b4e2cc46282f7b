"""Worst first: one suspicion score per loop and the loops ranked by it.

Performance-monitoring products meet a plant of hundreds of loops with a list of "bad
actors" ordered by how likely the fault and how much it costs (Paulonis & Cox 2003, "A
practical approach for large-scale controller performance assessment, diagnosis, and
improvement", J. Process Control 13: a prioritised list weighed by the loop's economic
importance). Here the fault is a sticky valve and the score is

    suspicion = p x w(A) x priority

* ``p``: the analysis' confidence of stiction (0-1; the site's calibration of it where the
  site has one, :mod:`.calibration`);
* ``w(A) = sqrt(clip(A / 1 %, 1/16, 16))``: what the cycle costs, from ``A``, the PV's
  amplitude in % of its span (half the range between its 2nd and 98th percentile over the
  window analysed, :func:`swing`): 1 at a cycle of 1 % of span, 2 at 4 %, 4 at 16 % or
  more, 1/4 at 1/16 % or less; 1 where the PV's span is not known (the square root: the
  amplitude moves a valve up the list, it does not outweigh the confidence);
* ``priority``: the plant's own weight of the loop (``priority`` in the gateway's config or
  tag list, a manifest's column; default 1, e.g. 3 for a loop on a product's quality).

The ranking puts loops in three tiers, worst first within each (ties keep the input order):

0. the loops judged on a cycle (``stiction``, ``undetermined``, ``no_stiction``) by their
   score; and a valve that does not respond (``valve_not_responding``: OP moves, PV does
   not follow), scored as certain (``p`` = 1, ``w`` = 1: it is checked first);
1. the followers of a plant-wide cycle (``propagated``): their cycle comes from another
   valve, fixed first; by their own score;
2. everything else, score 0, in input order: loops that are not oscillating, bad data,
   warming up, stale or not yet judged.

The order, not a threshold, is what carries from the development corpus to a plant: a
decision's thresholds may not fit a plant whose valves it never saw, while its ranking of
them does (issue 39).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import FloatArray

__all__ = ["AMPLITUDE_REF", "FOLLOWER", "JUDGED", "Ranked", "Suspect", "amplitude_weight",
           "rank", "rank_arrays", "suspicion", "swing", "verdict_order"]

AMPLITUDE_REF = 1.0
"""The PV amplitude (% of span) at which the cost weight is 1."""
WEIGHT_CLIP = (1.0 / 16.0, 16.0)
"""The bounds of ``A / AMPLITUDE_REF`` before its square root."""
JUDGED = frozenset({"stiction", "undetermined", "no_stiction"})
"""Verdicts judged on a cycle, scored by their confidence."""
NOT_RESPONDING = "valve_not_responding"
FOLLOWER = "propagated"
_VERDICT_ORDER = ("stiction", NOT_RESPONDING, "undetermined", "no_stiction", FOLLOWER,
                  "not_oscillating", "bad_data", "warming_up", "stale", "device_down", "none")


@dataclasses.dataclass(frozen=True)
class Suspect:
    """One loop as the ranking reads it: ``verdict`` (a verdict's name), ``confidence``
    (of stiction, 0-1; None: none), ``amplitude`` (the PV's, % of span; None: not known),
    ``priority`` (> 0)."""

    name: str
    verdict: str
    confidence: float | None = None
    amplitude: float | None = None
    priority: float = 1.0


@dataclasses.dataclass(frozen=True)
class Ranked:
    """One loop's place in the list: ``rank`` from 1 (the worst), ``score`` (the suspicion,
    0 in tier 2), ``tier`` (0, 1, 2: module doc), ``weight`` (``w(A) x priority``)."""

    name: str
    rank: int
    score: float
    tier: int
    weight: float


def amplitude_weight(amplitude: float | None) -> float:
    """``w(A)`` of the module doc; 1 for an unknown (None or not finite) amplitude."""
    if amplitude is None or not math.isfinite(amplitude):
        return 1.0
    lo, hi = WEIGHT_CLIP
    return math.sqrt(min(max(amplitude / AMPLITUDE_REF, lo), hi))


def suspicion(s: Suspect) -> tuple[int, float, float]:
    """``(tier, score, weight)`` of one loop (module doc)."""
    priority = s.priority if math.isfinite(s.priority) and s.priority > 0 else 1.0
    if s.verdict == NOT_RESPONDING:
        return 0, priority, priority
    weight = amplitude_weight(s.amplitude) * priority
    p = s.confidence if s.confidence is not None and math.isfinite(s.confidence) else 0.0
    p = min(max(p, 0.0), 1.0)
    if s.verdict in JUDGED:
        return 0, p * weight, weight
    if s.verdict == FOLLOWER:
        return 1, p * weight, weight
    return 2, 0.0, weight


def rank(suspects: Sequence[Suspect]) -> list[Ranked]:
    """The loops worst first (module doc), each with its rank from 1."""
    places, scores, tiers, weights = rank_arrays(
        [s.verdict for s in suspects],
        np.array([np.nan if s.confidence is None else s.confidence for s in suspects]),
        np.array([np.nan if s.amplitude is None else s.amplitude for s in suspects]),
        np.array([s.priority for s in suspects], dtype=np.float64))
    order = np.argsort(places, kind="stable")
    return [Ranked(suspects[k].name, int(places[k]), float(scores[k]), int(tiers[k]),
                   float(weights[k])) for k in order.tolist()]


def rank_arrays(verdicts: Sequence[str], confidence: FloatArray, amplitude: FloatArray,
                priority: FloatArray) -> tuple[NDArray[np.int64], FloatArray,
                                               NDArray[np.int64], FloatArray]:
    """:func:`rank` on arrays, one entry per loop (confidence and amplitude NaN where not
    known): each loop's place from 1, score, tier and weight, in the input's order (a few
    milliseconds for thousands of loops)."""
    n = len(verdicts)
    v = np.array(verdicts, dtype=object)
    prio = np.where(np.isfinite(priority) & (priority > 0), priority, 1.0)
    amp = np.where(np.isfinite(amplitude), amplitude, AMPLITUDE_REF) / AMPLITUDE_REF
    weight = np.sqrt(np.clip(amp, *WEIGHT_CLIP)) * prio
    p = np.clip(np.where(np.isfinite(confidence), confidence, 0.0), 0.0, 1.0)
    judged = np.isin(v, list(JUDGED))
    follower = v == FOLLOWER
    stuck = v == NOT_RESPONDING
    tier = np.where(judged | stuck, 0, np.where(follower, 1, 2)).astype(np.int64)
    score = np.where(judged | follower, p * weight, 0.0)
    score = np.where(stuck, prio, score)
    weight = np.where(stuck, prio, weight)
    order = np.lexsort((np.arange(n), -score, tier))
    places = np.empty(n, dtype=np.int64)
    places[order] = np.arange(1, n + 1)
    return places, score, tier, weight


def verdict_order(suspects: Sequence[Suspect]) -> list[str]:
    """The names in the verdicts' own order: ``stiction`` first, then a valve not
    responding, ``undetermined``, ``no_stiction``, ``propagated``, the rest; within a verdict
    the input order. What a list without a score gives (the baseline the ranking is measured
    against)."""
    place = {v: k for k, v in enumerate(_VERDICT_ORDER)}
    keyed = sorted(enumerate(suspects),
                   key=lambda ks: (place.get(ks[1].verdict, len(place)), ks[0]))
    return [s.name for _k, s in keyed]


def swing(pv: ArrayLike) -> float | None:
    """Half the range between the 2nd and the 98th percentile of the finite samples of
    ``pv`` (its units): the amplitude of a cycle, robust to a few spikes; None with fewer
    than 2 finite samples."""
    x = np.asarray(pv, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size < 2:
        return None
    lo, hi = np.percentile(x, [2.0, 98.0])
    return float(hi - lo) / 2.0
