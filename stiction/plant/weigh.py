"""Source evidence weighed against its own noise floor (issue 37, item 1), for
:mod:`.decide`: the margins by which one figure is clearly more than another, and which
loop's evidence is the stronger.

Each piece of a member's evidence has its floor: the nonlinearity index is already in
units of its surrogates' spread (1: three standard deviations, Thornhill 2005) and two
indices differ only by ``NLI_MARGIN`` or more; a Granger net flow counts from
``FLOW_LEADS`` (beyond the F test's 1 % level and the 0.03 independent loops show), names
by itself from ``FLOW_NAME``, and one loop leads another clearly by ``FLOW_MARGIN``; a
per-loop confidence and a valve score are clearly higher by ``CONF_MARGIN`` and
``VALVE_MARGIN``. Where the cycle has fewer than ``DIRECTION_SAMPLES`` samples a period the
band-passed cycle is mostly interpolation: in comparing two loops a lead counts only from
``FLOW_NAME`` and a nonlinearity only by twice its margin.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

from .nonlinearity import NLI_NONLINEAR
from .source import MemberEvidence

__all__ = ["CONF_MARGIN", "DIRECTION_SAMPLES", "FLOW_LEADS", "FLOW_MARGIN", "FLOW_NAME",
           "NLI_MARGIN", "VALVE_MARGIN", "Flow", "IndicatorEvidence", "nli_of", "shaped",
           "stronger", "trailed"]

FLOW_LEADS = 0.05
"""Net Granger flow (nats) from which a signal leads the others: independent loops show
under 0.03 either way on the project's plants, a source over 0.2."""
FLOW_MARGIN = 0.1
"""Net flow from a loop to a called loop from which the first overrides the second."""
FLOW_NAME = 0.3
"""Net flow from which direction (with nonlinearity or a valve) names a source by itself:
the loops an external cycle enters first lead the others by up to 0.27 on the project's
plants, a sticky valve's loop by 0.3-2. A called loop whose cycle trails by as much is not
named by its verdict alone."""
NLI_MARGIN = 0.5
"""A cycle is the most nonlinear of a group when its index is higher than the others' by
this (the index of one cycle varies by about this much from window to window)."""
CONF_MARGIN, VALVE_MARGIN = 0.05, 0.15
"""A per-loop confidence, a valve score clearly higher than another's by these (the spread
of each from one window of a loop to the next)."""
DIRECTION_SAMPLES = 8.0
"""Samples a period from which the cycle is resolved for comparing two loops' evidence
(:func:`stronger`; the shape tests' bound): below it (a historian's 60 s on a cycle of
minutes) the band-passed cycle is mostly interpolation, its net flow from one loop to
another varies by 0.1 or more either way from one realisation to the next and its
nonlinearity index by 0.7 (sticky-feeds-two at 60 s, 25 seeds)."""

@dataclasses.dataclass(frozen=True)
class IndicatorEvidence:
    """An indicator in a group: its ``strength``, its net Granger ``flow`` to the group's
    leading signals and the nonlinearity index of its cycle (None: not measured)."""

    name: str
    strength: float
    flow: float | None = None
    nli: float | None = None


Flow = Callable[[str, str], float]


def nli_of(e: MemberEvidence | IndicatorEvidence | None) -> float:
    return -1e9 if e is None or e.nli is None else e.nli


def stronger(a: MemberEvidence, b: MemberEvidence, flow: Flow | None, *,
             resolved: bool = True) -> bool:
    """Is ``a``'s own evidence of being the source clearly stronger than ``b``'s? Clearly
    more on more of its pieces than ``b`` is on its (a per-loop confidence higher by
    ``CONF_MARGIN``, a valve score by ``VALVE_MARGIN``, a nonlinear cycle more so by
    ``NLI_MARGIN``, its cycle leading the other's by ``FLOW_MARGIN``): a follower called at
    0.93 against a source at 0.72 whose valve, nonlinearity and lead all say more is the
    weaker. ``flow`` None: direction not measured. Where the cycle is not ``resolved``
    (under ``DIRECTION_SAMPLES`` samples a period) a nonlinearity counts only by twice
    ``NLI_MARGIN`` and a lead only by ``FLOW_NAME`` (three times the 0.1 by which a net flow
    varies there: a follower called at 0.98 at 60 s that trails by 0.6 is the weaker)."""
    lead = None if flow is None else flow(a.loop, b.loop)
    margin = NLI_MARGIN if resolved else 2.0 * NLI_MARGIN
    lead_margin = FLOW_MARGIN if resolved else FLOW_NAME

    def more(x: MemberEvidence, y: MemberEvidence, ahead: float | None) -> int:
        return sum(((x.confidence or 0.0) - (y.confidence or 0.0) >= CONF_MARGIN,
                    x.valve - y.valve >= VALVE_MARGIN,
                    nli_of(x) > NLI_NONLINEAR and nli_of(x) - nli_of(y) >= margin,
                    ahead is not None and ahead >= lead_margin))

    return more(a, b, lead) > more(b, a, None if lead is None else -lead)


def shaped(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence],
           counts: Callable[[IndicatorEvidence, MemberEvidence], bool] | None = None
           ) -> MemberEvidence | None:
    """Where the cycle is not resolved for direction (``DIRECTION_SAMPLES``): the loop whose
    cycle is nonlinear and the most nonlinear by twice ``NLI_MARGIN``, its net flow within
    ``FLOW_MARGIN`` of the highest of the others, loops' and indicators' (those ``counts``
    says count against it; None: all), or None (:mod:`.decide`, 3)."""
    measured = [e for e in ranking if e.nli is not None]
    if not measured:
        return None
    best = max(measured, key=nli_of)
    others = max((nli_of(e) for e in ranking if e is not best), default=-1e9)
    flows = [e.flow for e in ranking if e is not best and e.flow is not None] + \
        [i.flow for i in indicators
         if i.flow is not None and (counts is None or counts(i, best))]
    if nli_of(best) <= NLI_NONLINEAR or nli_of(best) < others + 2.0 * NLI_MARGIN or \
            best.flow is None or best.flow < max(flows, default=-1e9) - FLOW_MARGIN:
        return None
    return best


def trailed(e: MemberEvidence, ranking: Sequence[MemberEvidence], flow: Flow) -> bool:
    """Does another loop's cycle clearly lead ``e``'s (pairwise net flow at least
    ``FLOW_NAME``; loops whose direction was measured, ``e`` one of them)?"""
    if e.flow is None or e.flow > -FLOW_NAME / 2:
        return False  # (the mean over the group: no loop can lead it by as much)
    return any(t is not e and t.flow is not None and flow(t.loop, e.loop) >= FLOW_NAME
               for t in ranking)
