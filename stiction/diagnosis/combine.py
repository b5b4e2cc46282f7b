"""The weighted vote: one confidence from the tests' votes through a logistic link.

This was ``analyze``'s decision until the learned one (:mod:`.model`, issue 24) replaced it;
it stays as the baseline the benchmarks compare the learned decision against
(``python -m bench.train``, ``bench real_data``), and as a reading of the evidence that
needs no training.

``confidence = 1 / (1 + exp(-(BIAS + sum FOR[g] [g votes +1] - sum AGAINST[g] [g votes -1])))``

summed over the groups ``g`` of :data:`GROUPS`: every test is its own group but the two
stiction indices, which read one shape twice (OP and PV move together, so a triangle in one
is usually a triangle in the other) and count once: +1 when either says triangle and
neither says sine, -1 the other way round, else 0.

The weights (:mod:`.weights`) are fitted by ``bench/calibrate.py`` on the plant records,
the Tennessee Eastman runs and realistic simulations, each weight >= 0 and pulled towards 1,
and are printed there with the held-out scores. About: one test alone does not make a call,
two that agree with none against do. A window is called ``stiction`` at
``STICTION_CONFIDENCE`` or more and ``no_stiction`` (or ``not_oscillating``) at
``NO_STICTION_CONFIDENCE`` or less; in between the tests disagree or cannot tell:
``undetermined``. The confidence is calibrated for even prior odds (the calibration gives
sticky and other windows equal weight).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from .._assessment import Evidence
from . import weights as _weights

__all__ = ["GROUPS", "NO_STICTION_CONFIDENCE", "STICTION_CONFIDENCE", "confidence",
           "confidence_of", "group_votes", "score"]

STICTION_CONFIDENCE = 0.7
NO_STICTION_CONFIDENCE = 0.3
GROUPS = {"si_op": "shape", "si_pv": "shape"}
"""Tests that count as one vote (see the module doc); every other test is its own group."""


def group_votes(tests: Sequence[str], votes: Sequence[int]) -> dict[str, int]:
    """The vote of every group from the votes of its tests."""
    members: dict[str, list[int]] = {}
    for name, vote in zip(tests, votes, strict=True):
        members.setdefault(GROUPS.get(name, name), []).append(vote)
    out = {}
    for group, vs in members.items():
        up, down = any(v > 0 for v in vs), any(v < 0 for v in vs)
        out[group] = 1 if up and not down else -1 if down and not up else 0
    return out


def score(evidence: Iterable[Evidence]) -> float:
    """The weighted vote (log-odds of stiction)."""
    ev = list(evidence)
    return _score([e.test for e in ev], [e.vote for e in ev])


def _score(tests: Sequence[str], votes: Sequence[int]) -> float:
    z = _weights.BIAS
    for group, vote in group_votes(tests, votes).items():
        if vote > 0:
            z += _weights.FOR.get(group, 0.0)
        elif vote < 0:
            z -= _weights.AGAINST.get(group, 0.0)
    return z


def confidence(evidence: Iterable[Evidence]) -> float:
    """Probability-like confidence in [0, 1] that the window shows stiction."""
    return _logistic(score(evidence))


def confidence_of(tests: Sequence[str], votes: Sequence[int]) -> float:
    """:func:`confidence` from the tests' names and votes alone."""
    return _logistic(_score(tests, votes))


def _logistic(z: float) -> float:
    return 1.0 / (1.0 + math.exp(-z)) if z > -700 else 0.0
