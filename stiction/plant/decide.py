"""Which member of a group is its source, from the evidence of :mod:`.source` (one story per
loop).

In this order:

1. **From outside.** An indicator (a measured signal of no loop) leads the loops' cycle
   (its Granger net flow to the group's leading signals at least ``FLOW_LEADS`` and above
   every loop's), no loop called ``stiction`` has a nonlinear cycle (index above
   ``NLI_OUTSIDE``: its own valve may be the source), and no loop's cycle is nonlinear or
   the indicator's is the most nonlinear (Thornhill 2005: nonlinearity is strongest at the
   source): the cycle enters from outside the loops, named by that indicator; no loop is
   the source, a loop called ``stiction`` follows.
2. **A loop's own verdict.** A loop whose own window says ``stiction`` is the source (the
   best ranked of them), unless named evidence says otherwise: a loop ranked above it leads
   its cycle (net flow at least ``FLOW_MARGIN``) and has its own evidence (a valve score of
   at least ``SOURCE_SCORE``, or a cycle nonlinear and more so than the called loop's); then
   that loop is the source and both reasons say why.
3. **Its own valve.** Else the top candidate whose own valve evidence is enough
   (:attr:`.source.MemberEvidence.valve_named`), unless its cycle trails (net flow below 0,
   or below an indicator's).
4. **Direction.** Else the top candidate when it leads the group (the highest net flow,
   at least ``FLOW_LEADS``, above every indicator's) and its cycle is nonlinear (index
   above 1) and the most nonlinear of the loops (by ``NLI_MARGIN``, or with a net flow of
   ``FLOW_NAME``); or when it leads by ``FLOW_NAME`` and its valve score reaches
   ``SOURCE_SCORE`` (whatever its per-loop confidence: leading and a sticky valve that
   explains its PV agree).
5. Else no loop is named: none shows evidence of being the source (it may be outside the
   loops read, or not told from this data). No "enters from outside" without 1.

A called outer loop of a declared cascade whose inner loop is a member speaks for the inner
loop's valve (its "valve" is the inner loop): in 2 the inner loop takes its place, and the
outer loop follows. Every other member whose own verdict is ``stiction`` (or whose valve
names it) is led by the source (Granger gain from the source at least ``COUPLED`` and net
flow from it positive): a follower, its reason naming that evidence; or it is not: a source
of its own (two sticky valves at one period). A declared cascade's outer loop is never a
source of its own, nor taken from its inner loop.

Hysteresis (the gateway's successive rounds): a source named last round stays the source
while it is a member, still has evidence of its own at a lower bar (called ``stiction``, a
per-loop confidence of at least ``HOLD_CONFIDENCE`` or a valve score of half
``SOURCE_SCORE``), and no other member overrides it as in 2.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

from .nonlinearity import NLI_NONLINEAR
from .source import SOURCE_SCORE, MemberEvidence

__all__ = ["COUPLED", "FLOW_LEADS", "FLOW_MARGIN", "FLOW_NAME", "HOLD_CONFIDENCE",
           "NLI_MARGIN", "NLI_OUTSIDE", "Decision",
           "IndicatorEvidence", "decide"]

FLOW_LEADS = 0.05
"""Net Granger flow (nats) from which a signal leads the others: independent loops show
under 0.03 either way on the project's plants, a source over 0.2."""
FLOW_MARGIN = 0.1
"""Net flow from a loop to a called loop from which the first overrides the second."""
FLOW_NAME = 0.3
"""Net flow from which direction (with nonlinearity or a valve) names a source by itself:
the loops an external cycle enters first lead the others by up to 0.27 on the project's
plants, a sticky valve's loop by 0.3-2."""
NLI_MARGIN = 0.5
"""A cycle is the most nonlinear of a group when its index is higher than the others' by
this (the index of one cycle varies by about this much from window to window)."""
NLI_OUTSIDE = 1.0
"""Thornhill's bound of a linear cycle. A loop called ``stiction`` whose cycle is above it
keeps its call whatever an indicator shows: one read right after a sticky valve leads the
valve's loop and is more nonlinear than it (TEP's cooling water temperatures after their
valves: indices 5.7 against 3.3, 1.9 against 1.5)."""
COUPLED = 0.05
"""Granger gain from the source from which a member follows it."""
HOLD_CONFIDENCE = 0.5


@dataclasses.dataclass(frozen=True)
class IndicatorEvidence:
    """An indicator in a group: its ``strength``, its net Granger ``flow`` to the group's
    leading signals and the nonlinearity index of its cycle (None: not measured)."""

    name: str
    strength: float
    flow: float | None = None
    nli: float | None = None


@dataclasses.dataclass(frozen=True)
class Decision:
    """The source (None: no loop), other sources, which evidence named it, the indicator it
    enters by (``outside``), why each called loop that is not a source follows."""

    source: str | None
    also: tuple[str, ...]
    named_by: tuple[str, ...]
    outside: str | None
    demoted: Mapping[str, str]


Flow = Callable[[str, str], float]


def _nli(e: MemberEvidence | IndicatorEvidence | None) -> float:
    return -1e9 if e is None or e.nli is None else e.nli


def _outside(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence]
             ) -> IndicatorEvidence | None:
    """The indicator the cycle enters by from outside (module doc, 1), or None."""
    measured = [i for i in indicators if i.flow is not None]
    if not measured:
        return None
    lead = max(measured, key=lambda i: i.flow or 0.0)
    loop_flow = max((e.flow for e in ranking if e.flow is not None), default=-1e9)
    if (lead.flow or 0.0) < FLOW_LEADS or (lead.flow or 0.0) <= loop_flow:
        return None
    if any(e.called and _nli(e) > NLI_OUTSIDE for e in ranking):
        return None  # a loop's own call and its nonlinear cycle: its valve may be the source
    most = max((_nli(e) for e in ranking), default=-1e9)
    return lead if most <= NLI_OUTSIDE or _nli(lead) >= most else None


def _overrides(t: MemberEvidence, s: MemberEvidence, flow: Flow,
               cascades: Mapping[str, str]) -> bool:
    """Does ``t`` take the source's place from called loop ``s`` (module doc, 2)?"""
    if cascades.get(t.loop) == s.loop or t.loop == s.loop:
        return False  # the outer loop of a cascade: its valve is s
    own = t.valve >= SOURCE_SCORE or (_nli(t) > NLI_NONLINEAR and _nli(t) > _nli(s))
    return own and flow(t.loop, s.loop) >= FLOW_MARGIN


def _leads(top: MemberEvidence, ranking: Sequence[MemberEvidence],
           indicators: Sequence[IndicatorEvidence]) -> list[str]:
    """The evidence that names ``top`` by direction (module doc, 4): it leads the group
    (net flow at least ``FLOW_LEADS``, the highest, above every indicator's) and its cycle
    is nonlinear and the most nonlinear, by ``NLI_MARGIN`` or with a net flow of
    ``FLOW_NAME``; or it leads by ``FLOW_NAME`` and its valve score reaches
    ``SOURCE_SCORE``."""
    flow = top.flow or 0.0
    if flow < FLOW_LEADS or flow < max(e.flow or 0.0 for e in ranking) or \
            flow <= max((i.flow for i in indicators if i.flow is not None), default=-1e9):
        return []
    others = max((_nli(e) for e in ranking if e is not top), default=-1e9)
    if _nli(top) > NLI_NONLINEAR and _nli(top) >= others and \
            (flow >= FLOW_NAME or _nli(top) >= others + NLI_MARGIN):
        return ["direction", "nonlinearity"]
    return ["direction", "own valve"] if flow >= FLOW_NAME and top.valve >= SOURCE_SCORE \
        else []


def _holds(e: MemberEvidence) -> bool:
    return e.called or (e.confidence or 0.0) >= HOLD_CONFIDENCE or e.valve >= SOURCE_SCORE / 2


def _trails(e: MemberEvidence, indicators: Sequence[IndicatorEvidence]) -> bool:
    """Does ``e``'s cycle come after the others' (net flow below 0, or below an
    indicator's)?"""
    if e.flow is None:
        return False
    return e.flow < 0 or e.flow < max((i.flow for i in indicators if i.flow is not None),
                                      default=-1e9)


def _choose(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence],
            flow: Flow, cascades: Mapping[str, str], previous: str | None
            ) -> tuple[MemberEvidence | None, list[str], str | None]:
    """(source, named_by, the called loop it overrides)."""
    top = ranking[0]
    by_name = {e.loop: e for e in ranking}
    # a called outer loop of a cascade speaks for its inner loop's valve, when that is here
    called = list(dict.fromkeys(by_name.get(cascades.get(e.loop, ""), e) for e in ranking
                                if e.called))
    source: MemberEvidence | None = None
    named: list[str] = []
    over: str | None = None
    if called:
        best = called[0]
        if top is not best and _overrides(top, best, flow, cascades):
            source, over = top, best.loop
            named = ["own valve"] if top.valve >= SOURCE_SCORE else ["nonlinearity"]
            named.append("direction")
        else:
            source = best
            named = ["own verdict"] if best.called else \
                ["own verdict of its cascade's outer loop"]
    elif top.valve_named and not _trails(top, indicators):
        source, named = top, ["own valve"]
    elif _leads(top, ranking, indicators):
        source, named = top, _leads(top, ranking, indicators)
    held = next((e for e in ranking if e.loop == previous), None)
    if held is not None and held is not source and _holds(held) and \
            (source is None or not _overrides(source, held, flow, cascades)):
        source, named, over = held, ["held: named in the last round, its evidence stands"], None
    if source is not None:
        if "direction" not in named and source.flow is not None and source.flow >= FLOW_LEADS \
                and source.flow >= max((e.flow or 0.0) for e in ranking):
            named.append("direction")
        if "nonlinearity" not in named and _nli(source) > NLI_NONLINEAR and \
                _nli(source) >= max(_nli(e) for e in ranking):
            named.append("nonlinearity")
    return source, named, over


def decide(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence],
           flow: Flow, granger: Flow, *, cascades: Mapping[str, str],
           previous: str | None = None) -> Decision:
    """The group's source from its members' ``ranking`` (best first) and its indicators;
    ``flow(a, b)``: net Granger flow from a to b, ``granger(a, b)``: the gain from a to b
    (measured on demand); ``previous``: the source named last round (module doc)."""
    ind = _outside(ranking, indicators)
    demoted: dict[str, str] = {}
    if ind is not None:
        for e in ranking:
            if e.called:
                demoted[e.loop] = (f"indicator {ind.name} leads its cycle (Granger net flow "
                                   f"{ind.flow:+.2f}): the cycle enters from outside the loops")
        return Decision(None, (), ("indicator",), ind.name, demoted)
    source, named, over = _choose(ranking, indicators, flow, cascades, previous)
    also: list[str] = []
    for e in ranking:
        if source is None or e is source or not (e.called or e.valve_named):
            continue
        if cascades.get(e.loop) == source.loop:
            demoted[e.loop] = (f"its valve is {source.loop}'s: the outer loop of a cascade whose "
                               "inner loop is the source")
            continue
        led = granger(source.loop, e.loop)
        net = flow(source.loop, e.loop)
        if (led >= COUPLED and net > 0) or e.loop == over:
            demoted[e.loop] = (f"{source.loop} leads its cycle (Granger net flow {net:+.2f}"
                               + (f"; {source.loop} is named by {', '.join(named)}"
                                  if e.loop == over else "") + ")")
        elif e.called or e.loop not in cascades:
            also.append(e.loop)
    return Decision(None if source is None else source.loop, tuple(also), tuple(named), None,
                    demoted)
