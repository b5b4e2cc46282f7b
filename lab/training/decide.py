"""``python -m lab decide`` (issue 36 item 2): the call analyze ships beside today's decision,
the shape network alone and the other ways of joining the two, all held out, in one run.

Every candidate is scored on the rows of ``python -m lab train`` (lab/features/rows.py: each
window analysed as the gateway would, with the network's logit) with the learned decision's
probability held out (leave one source out, :func:`lab.training.fit.held_out`'s folds). The
fold that never saw a real record is the plant records' (their decision fitted without them;
the network never saw them): its figures are printed first and choose the call. What a
candidate fits beyond the decision (a blend's weights, a retrained decision's threshold) is
fitted **without the plant records** too: on held-out scores of decisions fitted without
the plant records and without the scored source (nested), so that no figure of the plant
fold saw a plant label.

The candidates (:func:`candidates`):

- ``today``: the learned decision at model.json's ``stiction_at`` (0.87), the evidence gate of
  the registered tests (the network not in it);
- ``network``: the shape network alone at its threshold chosen on simulation (0.690);
- ``retrained``: the decision retrained with the network's logit as one more feature (its
  vote-like constraint: it can only raise the score), at the F0.5 threshold of its held-out
  scores without the plant records; the network's vote in the gate;
- ``blend``: a logistic regression of the decision's and the network's logits (and whether
  the network read the window) fitted on those held-out scores, at its F0.5 threshold there;
- ``and``: today's call where the network is not under its ``band_low``;
- ``shipped``: :func:`stiction.diagnosis.call.call` as analyze applies it (the network first,
  the decision where the network does not object or cannot read);
- ``shipped, site``: the same with the network's probability moved to each fold's share of
  sticky windows (label-shift EM over the fold's windows as one batch,
  :func:`stiction.diagnosis.adapt.estimate`): site adaptation on.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from stiction import Verdict
from stiction.diagnosis import adapt, network, shape
from stiction.diagnosis.call import Thresholds, call, shipped
from stiction.diagnosis.features import NAMES, TEST_OF
from stiction.signal.oscillation import MIN_PERIOD

from .. import _cache
from ..features.rows import Row
from .fit import SETTINGS, _data, f_beta

PLANT = "plant"
VOTES = [(i, TEST_OF[n]) for i, n in enumerate(NAMES) if n.endswith(".vote")]
PERIOD = NAMES.index("cycle.period")


@dataclasses.dataclass(frozen=True)
class Scored:
    """The scored rows (``idx`` into the rows) and what every candidate reads of them:
    source, sticky, tag (the run), the decision held out (``p0``: today's features; ``p1``:
    with the network's logit; ``*_np``: fitted without the plant records too, NaN on them),
    the network's Platt probability (NaN: not read), the tests' votes, the cycle too fast,
    withdrawn (too short for a call)."""

    idx: np.ndarray
    src: np.ndarray
    y: np.ndarray
    tag: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    p0_np: np.ndarray
    p1_np: np.ndarray
    net: np.ndarray
    votes: list[dict[str, int]]
    too_fast: np.ndarray
    withdrawn: np.ndarray
    weight: np.ndarray


def _fit(x: np.ndarray, y: np.ndarray, w: np.ndarray, mono: list[int]) -> Any:
    from sklearn.ensemble import HistGradientBoostingClassifier  # noqa: PLC0415  (bench extra)

    return HistGradientBoostingClassifier(random_state=0, monotonic_cst=mono,
                                          **SETTINGS[0]).fit(x, y, sample_weight=w)


def _held_out(x: np.ndarray, y: np.ndarray, w: np.ndarray, src: np.ndarray,
              mono: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Leave one source out; and the same without the plant records (NaN on them)."""
    p, p_np = np.full(y.size, np.nan), np.full(y.size, np.nan)
    for s in sorted(set(src.tolist())):
        test = src == s
        p[test] = _fit(x[~test], y[~test], w[~test], mono).predict_proba(x[test])[:, 1]
        if s != PLANT:
            train = ~test & (src != PLANT)
            p_np[test] = _fit(x[train], y[train], w[train], mono).predict_proba(x[test])[:, 1]
        print(f"  held out: {s}", flush=True)
    return p, p_np


def key(x: np.ndarray, logit: np.ndarray, y: np.ndarray, src: np.ndarray) -> str:
    """What the held-out scores depend on: the features, the network's logits, the labels,
    the folds, to 9 decimals (a change to analyze that leaves them alone, or moves them by
    rounding, fits nothing again)."""
    h = hashlib.sha256()
    for a in (x, logit, y):
        h.update(np.round(np.ascontiguousarray(a, dtype=np.float64), 9).tobytes())
    h.update("\n".join(src.tolist()).encode())
    h.update(repr(SETTINGS).encode())
    return h.hexdigest()[:16]


def score(rs: Sequence[Row]) -> Scored:
    """Every held-out score (cached in the lab's cache by :func:`key`)."""
    idx, x0, y, w = _data(rs)
    logit = np.array([rs[i].shape for i in idx])
    src = np.array([rs[i].source for i in idx])
    path = _cache.root() / f"decide-{key(x0, logit, y, src)}.pickle"
    if path.exists():
        p0, p0_np, p1, p1_np = _cache.load(path)
    else:
        mono = [1 if n.endswith(".vote") else 0 for n in NAMES]
        p0, p0_np = _held_out(x0, y, w, src, mono)
        p1, p1_np = _held_out(np.column_stack([x0, logit]), y, w, src, [*mono, 1])
        _cache.dump((p0, p0_np, p1, p1_np), path)
    net_model = shape.load()
    read = ~np.isnan(logit)
    net = np.where(read, shape.calibrated(net_model, np.nan_to_num(logit)), np.nan)
    votes = [{t: int(x0[k, j]) for j, t in VOTES if not math.isnan(x0[k, j])}
             for k in range(idx.size)]
    period = x0[:, PERIOD]
    return Scored(idx, src, y, np.array([rs[i].run for i in idx]), p0, p1, p0_np, p1_np, net,
                  votes, np.nan_to_num(period, nan=np.inf) < MIN_PERIOD,
                  np.array([rs[i].withdrawn for i in idx]), w)


def _logit(p: np.ndarray) -> np.ndarray:
    q = np.clip(p, 1e-6, 1 - 1e-6)
    return np.asarray(np.log(q / (1 - q)), dtype=np.float64)


def _f05_threshold(p: np.ndarray, y: np.ndarray) -> float:
    """The F0.5-best threshold of the held-out scores without the plant records."""
    m = ~np.isnan(p)
    pooled = list(zip(p[m].tolist(), y[m].tolist(), strict=True))
    return float(max(np.arange(0.5, 0.99, 0.01), key=lambda t: f_beta(pooled, float(t))))


def _calls(s: Scored, dec: np.ndarray, net: np.ndarray, at: Thresholds
           ) -> tuple[np.ndarray, np.ndarray]:
    """The shipped call on every row: (stiction, confidence)."""
    out = [call(float(d), None if math.isnan(n) else float(n), v, too_fast=bool(f), at=at)
           for d, n, v, f in zip(dec, net, s.votes, s.too_fast, strict=True)]
    called = np.array([c.verdict == Verdict.STICTION for c in out]) & ~s.withdrawn
    return called, np.array([c.confidence for c in out])


def _gated(s: Scored, net_votes: bool) -> np.ndarray:
    """Rows whose stiction the evidence gate lets through (the network's vote in it or
    not), not withdrawn."""
    _, hi = network.thresholds()
    ok = []
    for v, n, fast in zip(s.votes, s.net, s.too_fast, strict=True):
        if fast:
            ok.append(v.get("fast_cycle", 0) > 0)
        else:
            ok.append(any(x > 0 for x in v.values()) or (net_votes and n >= hi))
    out: np.ndarray = np.array(ok) & ~s.withdrawn
    return out


def _at_sites(s: Scored) -> np.ndarray:
    """The network's probabilities moved to each source's share (one batch a source)."""
    out = s.net.copy()
    for src in set(s.src.tolist()):
        m = (s.src == src) & ~np.isnan(s.net)
        site = adapt.estimate(s.net[m].tolist())
        out[m] = [adapt.at_site(float(p), site) for p in s.net[m]]
    return out


def candidates(s: Scored) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Candidate name -> (called stiction, confidence) on every scored row (module doc)."""
    from sklearn.linear_model import LogisticRegression  # noqa: PLC0415  (bench extra)

    at = shipped()
    read = ~np.isnan(s.net)
    gate0, gate1 = _gated(s, False), _gated(s, True)
    out = {"today": ((s.p0 >= at.stiction_at) & gate0, s.p0),
           "network": ((s.net >= at.threshold) & ~s.withdrawn, np.nan_to_num(s.net))}
    t1 = _f05_threshold(s.p1_np, s.y)
    out[f"retrained ({t1:.2f})"] = ((s.p1 >= t1) & gate1, s.p1)

    def z(dec: np.ndarray) -> np.ndarray:
        return np.column_stack([_logit(np.nan_to_num(dec, nan=0.5)),
                                np.where(read, _logit(np.nan_to_num(s.net, nan=0.5)), 0.0),
                                (~read).astype(float)])
    train = s.src != PLANT
    lr = LogisticRegression(C=10.0).fit(z(s.p0_np)[train], s.y[train],
                                        sample_weight=s.weight[train])
    blend, blend_np = lr.predict_proba(z(s.p0))[:, 1], lr.predict_proba(z(s.p0_np))[:, 1]
    tb = _f05_threshold(np.where(train, blend_np, np.nan), s.y)
    out[f"blend ({tb:.2f})"] = ((blend >= tb) & gate1, blend)
    out["and"] = ((s.p0 >= at.stiction_at) & gate0 & ~(s.net < at.band_low), s.p0)
    out["shipped"] = _calls(s, s.p0, s.net, at)
    out["shipped, site"] = _calls(s, s.p0, _at_sites(s), at)
    return out
