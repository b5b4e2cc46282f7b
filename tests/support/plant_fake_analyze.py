"""stiction.analyze, but an oscillating loop it does not call sticky is called sticky
anyway (confidence 0.9): the per-loop view that suspects every follower, which the
gateway's plant step must correct."""

from __future__ import annotations

import dataclasses
from typing import Any

from stiction import Assessment, Verdict
from stiction import analyze as real_analyze


def analyze(op: Any, pv: Any, **kw: Any) -> Assessment:
    a = real_analyze(op, pv, **kw)
    if a.verdict in (Verdict.NO_STICTION, Verdict.UNDETERMINED) and a.period_s is not None:
        return dataclasses.replace(a, verdict=Verdict.STICTION,
                                   confidence=max(a.confidence or 0.0, 0.9),
                                   reason="suspected: " + a.reason)
    return a
