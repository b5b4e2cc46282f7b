"""python -m lab decide (lab/training/decide.py) without the built corpus: the candidates on a
few synthetic scored windows, the shipped one exactly the product's call, and the cache key
of the held-out scores."""

from __future__ import annotations

import numpy as np
import pytest

from lab.training import decide
from stiction import Verdict
from stiction.diagnosis.call import call, shipped

pytest.importorskip("sklearn")


def _scored() -> decide.Scored:
    """Twelve windows of three sources: sticky ones the network reads high, good ones low;
    one the network cannot read; one too short for a call."""
    rng = np.random.default_rng(36)
    n = 12
    y = np.array([i % 2 == 0 for i in range(n)])
    src = np.array(["plant"] * 4 + ["realistic"] * 4 + ["tep-mode1"] * 4)
    net = np.where(y, 0.9, 0.05) + rng.uniform(-0.02, 0.02, n)
    net[5] = np.nan  # not read
    p = np.where(y, 0.3, 0.2)
    p[5] = 0.95
    votes = [{"si_op": 0, "horch": -1} for _ in range(n)]
    votes[5] = {"si_op": 1}
    withdrawn = np.zeros(n, bool)
    withdrawn[2] = True
    return decide.Scored(np.arange(n), src, y, np.array([f"t{i}" for i in range(n)]), p, p,
                         np.where(src == "plant", np.nan, p), np.where(src == "plant", np.nan, p),
                         net, votes, np.zeros(n, bool), withdrawn, np.ones(n))


def test_the_shipped_candidate_is_the_products_call() -> None:
    s = _scored()
    cands = decide.candidates(s)
    called, conf = cands["shipped"]
    at = shipped()
    for i in range(s.y.size):
        n = None if np.isnan(s.net[i]) else float(s.net[i])
        c = call(float(s.p0[i]), n, s.votes[i], too_fast=False, at=at)
        assert called[i] == (c.verdict == Verdict.STICTION and not s.withdrawn[i])
        assert conf[i] == c.confidence
    assert called.tolist() == [True, False, False, False, True, True, True, False, True,
                               False, True, False]  # the withdrawn sticky window is not
    net_called, _ = cands["network"]
    assert not net_called[5] and net_called[0]  # the network alone cannot call what it
    today, _ = cands["today"]                    # did not read; the decision can
    assert today[5] and not today[0]


def test_the_held_out_scores_are_kept_by_what_they_depend_on() -> None:
    x, logit = np.ones((3, 2)), np.array([0.1, np.nan, 2.0])
    y, src = np.array([True, False, True]), np.array(["a", "b", "c"])
    k = decide.key(x, logit, y, src)
    assert k == decide.key(x.copy(), logit.copy(), y, src)
    assert k != decide.key(x, np.array([0.1, np.nan, 2.5]), y, src)
    assert k != decide.key(x, logit, y, np.array(["a", "b", "b"]))
