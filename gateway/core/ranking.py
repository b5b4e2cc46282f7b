"""The list the crew works from, kept in the result store: every loop's place worst first
and its suspicion (:mod:`stiction.ranking.suspicion`: the confidence of stiction, the
site's where it has one, times what the cycle costs: the PV's amplitude in % of its span
where the config gives the PV a ``range``, times the loop's ``priority``).

:func:`weigh` sets each loop's weights from the config (at start and at every reload);
:func:`rerank` ranks the store's latest results and publishes the places and scores
(``ResultStore.set_ranks``: the outputs hear of the loops that moved). A loop whose device is
down or whose samples are stale keeps the place its latest assessment gives it: the valve did
not change because a link dropped. Ranking 2,000 loops takes a few milliseconds, once per
analysis round (the scores and the order in numpy).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stiction.ranking import Suspect, rank_arrays

from ..config.model import LoopConfig
from .store import LoopResult, ResultStore

__all__ = ["amplitude_percent", "rerank", "suspects", "weigh"]


def weigh(store: ResultStore, loops: Sequence[LoopConfig]) -> None:
    """Each loop's priority and its PV's span (the width of its ``range``; NaN: none)."""
    for lp in loops:
        i = store.index.get(lp.name)
        if i is None:
            continue
        store.priority[i] = lp.priority
        rng = lp.pv.range
        store.pv_span[i] = np.nan if rng is None else rng[1] - rng[0]


def amplitude_percent(result: LoopResult | None, span: float) -> float | None:
    """The PV's amplitude in % of its span, or None where either is unknown."""
    if result is None or result.pv_swing is None or not np.isfinite(span) or span <= 0:
        return None
    return 100.0 * result.pv_swing / span


def suspects(store: ResultStore) -> list[Suspect]:
    """Every loop of ``store`` with an assessment, as the ranking reads it, in config
    order."""
    out = []
    for i, name in enumerate(store.loops):
        res = store.results[i]
        if res is None:
            continue
        a = res.assessment
        out.append(Suspect(name, str(a.verdict), a.confidence,
                           amplitude_percent(res, float(store.pv_span[i])),
                           float(store.priority[i])))
    return out


def rerank(store: ResultStore) -> None:
    """Rank the store's loops that have an assessment and publish each one's place and
    suspicion (a loop without one: place 0, suspicion NaN)."""
    n = len(store.loops)
    rows = [i for i in range(n) if store.results[i] is not None]
    verdicts, conf, swing = [], np.full(len(rows), np.nan), np.full(len(rows), np.nan)
    for k, i in enumerate(rows):
        res = store.results[i]
        assert res is not None
        verdicts.append(str(res.assessment.verdict))
        if res.assessment.confidence is not None:
            conf[k] = res.assessment.confidence
        if res.pv_swing is not None:
            swing[k] = res.pv_swing
    idx = np.array(rows, dtype=np.intp)
    span = store.pv_span[idx]
    with np.errstate(invalid="ignore", divide="ignore"):
        amplitude = np.where(span > 0, 100.0 * swing / span, np.nan)
    places_of, scores_of, _tiers, _weights = rank_arrays(verdicts, conf, amplitude,
                                                         store.priority[idx])
    places = np.zeros(n, dtype=np.int64)
    scores = np.full(n, np.nan)
    places[idx], scores[idx] = places_of, scores_of
    store.set_ranks(places, scores)
