"""Calibrate how the tests' votes combine into one confidence, on real and simulated loops.

Each window's evidence (:func:`stiction.diagnosis.evidence.gather`, the tests :func:`analyze` runs)
gives every test a vote: +1 stiction, -1 not, 0 cannot tell. The combination is a weighted
vote through a logistic link,

    confidence = 1 / (1 + exp(-(bias + sum_t w_t^+ [vote_t = +1] - w_t^- [vote_t = -1])))

with every weight >= 0 (a test saying stiction can only raise the confidence, one saying
not can only lower it) and an L2 penalty that pulls each weight towards ``PRIOR`` (1: every
published test counts the same until the data show otherwise). Without that pull the
weights shrink towards 0 wherever the data are noisy, and three tests agreeing with none
against would stay short of a call. Two weights a test, a bias: small enough to read
and to ship in the package (:mod:`stiction.diagnosis.weights`), too small to learn any one record.

Data: the plant records (grouped by tag), the Tennessee Eastman runs (by run) and the
realistic simulations (by loop), the real data sets weighing 0.4 each and the simulations
0.2 (``DATASET_WEIGHT``), within each the sticky and the other windows half each (so the
confidence is for even prior odds), within the plant records each tag equally (23 of 35
sticky records are one valve). Scores are cross-validated by group, never by record: five
folds of groups, and leave-one-data-set-out (fit on two, score the third), which is the
nearest we have to loops from elsewhere.

``python -m lab calibrate`` prints the held-out folds; ``python -m lab calibrate --write``
also rewrites ``stiction/diagnosis/weights.py`` from the fit on all data
(lab/export/weights.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import optimize

from stiction.diagnosis.combine import group_votes
from stiction.diagnosis.evidence import TESTS, gather_for_calibration

from ..sources.realistic import AMBIGUOUS, sim_cases
from ..sources.records import Case, plant_cases, tep_cases

GROUP_NAMES = tuple(group_votes(TESTS, [0] * len(TESTS)))

L2 = 0.02
PRIOR = 1.0
DATASET_WEIGHT = {"plant": 0.4, "tep": 0.4, "sim": 0.2}
"""Real loops first: a rule that only holds on our own simulator is a defect, so the
simulations weigh half as much as each real data set."""
FOLDS = 5


@dataclasses.dataclass
class Table:
    cases: list[Case]
    votes: np.ndarray  # (cases, tests) in {-1, 0, 1}
    sticky: np.ndarray
    weight: np.ndarray
    groups: np.ndarray  # group index per case

    def subset(self, mask: np.ndarray) -> Table:
        return Table([c for c, m in zip(self.cases, mask, strict=True) if m], self.votes[mask],
                     self.sticky[mask], self.weight[mask], self.groups[mask])


def _design(votes: np.ndarray) -> np.ndarray:
    """Columns: a constant, then per test [vote = +1] and -[vote = -1]."""
    pos = (votes > 0).astype(np.float64)
    neg = -(votes < 0).astype(np.float64)
    return np.column_stack([np.ones(len(votes)), pos, neg])


def fit(t: Table, l2: float = L2) -> np.ndarray:
    """Bias and non-negative weights (see the module doc) minimising the weighted
    log-loss plus ``l2`` times the squared distance of the weights from ``PRIOR``."""
    x = _design(t.votes)
    w = t.weight / t.weight.sum()
    y = t.sticky.astype(np.float64)

    def loss(beta: np.ndarray) -> tuple[float, np.ndarray]:
        z = x @ beta
        p = 1.0 / (1.0 + np.exp(-z))
        eps = 1e-12
        ll = -np.sum(w * (y * np.log(p + eps) + (1 - y) * np.log(1 - p + eps)))
        grad = x.T @ (w * (p - y))
        dev = beta[1:] - PRIOR
        ll += l2 * float(dev @ dev)
        grad[1:] += 2 * l2 * dev
        return float(ll), grad

    bounds = [(None, None)] + [(0.0, None)] * (x.shape[1] - 1)
    start = np.full(x.shape[1], PRIOR)
    start[0] = 0.0
    res = optimize.minimize(loss, start, jac=True, method="L-BFGS-B",
                            bounds=bounds)
    return np.asarray(res.x)


def confidence(beta: np.ndarray, votes: np.ndarray) -> np.ndarray:
    return np.asarray(1.0 / (1.0 + np.exp(-(_design(votes) @ beta))))


def load(per_seed: int = 14) -> Table:
    cases = plant_cases() + tep_cases() + [c for c in sim_cases(per_seed)
                                           if c.cause not in AMBIGUOUS]
    votes = np.array([list(group_votes(TESTS, gather_for_calibration(c.op, c.pv, ts=c.ts))
                           .values()) for c in cases])
    sticky = np.array([c.sticky for c in cases])
    names = sorted({(c.dataset, c.group) for c in cases})
    index = {g: i for i, g in enumerate(names)}
    groups = np.array([index[(c.dataset, c.group)] for c in cases])
    per_group = np.bincount(groups)
    weight = 1.0 / per_group[groups]  # each group (tag, run, loop) counts once
    for ds, share in DATASET_WEIGHT.items():
        for label in (True, False):  # each data set its share, its two classes half each
            m = np.array([c.dataset == ds and c.sticky == label for c in cases])
            weight[m] *= share / weight[m].sum()
    return Table(cases, votes, sticky, weight, groups)


def _score(t: Table, p: np.ndarray, hi: float) -> str:
    call = p >= hi
    s = t.sticky
    tpr = float(np.mean(call[s])) if s.any() else float("nan")
    tnr = float(np.mean(~call[~s])) if (~s).any() else float("nan")
    return (f"sticky found {int(call[s].sum()):>3}/{int(s.sum()):<3} false calls "
            f"{int(call[~s].sum()):>3}/{int((~s).sum()):<3} bal.acc "
            f"{np.nanmean([tpr, tnr]):.2f}")


def cross_validate(t: Table, hi: float) -> None:
    rng = np.random.default_rng(0)
    ug = np.unique(t.groups)
    fold_of = dict(zip(ug.tolist(), rng.permutation(len(ug)) % FOLDS, strict=True))
    folds = np.array([fold_of[g] for g in t.groups.tolist()])
    held = np.empty(len(t.cases))
    print(f"  {FOLDS} folds by group (tag / run / loop), held-out scores at confidence >= {hi}:")
    for k in range(FOLDS):
        test = folds == k
        beta = fit(t.subset(~test))
        held[test] = confidence(beta, t.votes[test])
        print(f"    fold {k}: {_score(t.subset(test), held[test], hi)}")
    for ds in ("plant", "tep", "sim"):
        m = np.array([c.dataset == ds for c in t.cases])
        print(f"    all folds, {ds:<5}: {_score(t.subset(m), held[m], hi)}")
    print("  leave one data set out (fit on the other two):")
    for ds in ("plant", "tep", "sim"):
        m = np.array([c.dataset == ds for c in t.cases])
        beta = fit(t.subset(~m))
        print(f"    {ds:<5}: {_score(t.subset(m), confidence(beta, t.votes[m]), hi)}")
