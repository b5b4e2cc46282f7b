"""One confidence from the tests' votes: a weighted vote through a logistic link.

``confidence = 1 / (1 + exp(-(BIAS + sum FOR[t] [t votes +1] - sum AGAINST[t] [t votes -1])))``

The weights (:mod:`._weights`) are fitted by ``bench/calibrate.py`` on the plant records,
the Tennessee Eastman runs and realistic simulations, each test's weight >= 0, and are
printed there with the held-out scores. A window is called ``stiction`` at
``STICTION_CONFIDENCE`` or more and ``no_stiction`` (or ``not_oscillating``) at
``NO_STICTION_CONFIDENCE`` or less; in between the tests disagree or cannot tell:
``undetermined``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from . import _weights
from ._assessment import Evidence

__all__ = ["NO_STICTION_CONFIDENCE", "STICTION_CONFIDENCE", "confidence", "score"]

STICTION_CONFIDENCE = 0.7
NO_STICTION_CONFIDENCE = 0.3


def score(evidence: Iterable[Evidence]) -> float:
    """The weighted vote (log-odds of stiction)."""
    z = _weights.BIAS
    for e in evidence:
        if e.vote > 0:
            z += _weights.FOR.get(e.test, 0.0)
        elif e.vote < 0:
            z -= _weights.AGAINST.get(e.test, 0.0)
    return z


def confidence(evidence: Iterable[Evidence]) -> float:
    """Probability-like confidence in [0, 1] that the window shows stiction."""
    z = score(evidence)
    return 1.0 / (1.0 + math.exp(-z)) if z > -700 else 0.0
