"""Which member of a group is its source, from the evidence of :mod:`.source` (one story per
loop). Each piece of evidence counts by how strong it is against its own noise floor (issue
37): the nonlinearity index is already in units of its surrogates' spread (1: three standard
deviations) and two indices differ only by ``NLI_MARGIN`` or more; a Granger flow counts from
``FLOW_LEADS`` (beyond the F test's 1 % level and the 0.03 independent loops show) and names
by itself from ``FLOW_NAME``; membership has its margins (:mod:`.groups`). A verdict is
overturned only by stronger evidence.

In this order:

1. **A loop's own verdict.** A loop whose own window says ``stiction`` is the source (the
   best ranked of them, one called at ``CONFIDENT`` or more first), unless named evidence
   says otherwise: a loop ranked above it leads its cycle (net flow at least
   ``FLOW_MARGIN``) and has its own evidence (a valve score of at least ``SOURCE_SCORE``,
   a cycle nonlinear and more so than the called loop's, or half that valve score and
   stronger evidence than the called loop's, :func:`.weigh.stronger`); then that loop is
   the source and both reasons say why. A called loop whose cycle clearly trails another
   loop's (pairwise net flow ``FLOW_NAME`` or more from it) is not named by its verdict
   alone.
2. **Its own valve.** Else the top candidate whose own valve evidence is enough
   (:attr:`.source.MemberEvidence.valve_named`), unless its cycle trails (net flow below 0,
   or below that of an indicator whose cycle is the clearly nonlinear one while the loop's
   is linear, as in 4). An indicator that leads it otherwise (one read between its valve
   and its PV: a second gauge before a slow transmitter, a cooling-water temperature right
   after the valve) leads it through the loop's own dynamics: *also fed from outside*.
3. **Direction.** Else the top candidate when it leads the group (the highest net flow,
   at least ``FLOW_LEADS``, above every indicator's) and its cycle is nonlinear (index
   above 1) and the most nonlinear of the loops (a declared outer loop of its cascade
   aside: its valve is the top candidate) by ``NLI_MARGIN``, or with a net flow of
   ``FLOW_NAME``; a lead under ``FLOW_NAME`` does not name a loop whose valve fit clears
   its valve (fitted, a valve score under half ``SOURCE_SCORE``: the loop a square load
   from outside enters first leads weakly with a nonlinear cycle too). Or when it leads by
   ``FLOW_NAME`` and its valve score reaches ``SOURCE_SCORE`` (whatever its per-loop
   confidence: leading and a sticky valve that explains its PV agree). Where the cycle has
   fewer than ``DIRECTION_SAMPLES`` samples a period (a historian's 30 or 60 s on a cycle
   of minutes) a net flow of 0.1 either way is noise: there the loop whose cycle is the
   most nonlinear by twice ``NLI_MARGIN`` and does not clearly trail (net flow within
   ``FLOW_MARGIN`` of the others') is named by its nonlinearity. An indicator's lead does
   not count against a loop whose own window suspects its valve (``CONFIDENT``) and whose
   cycle is nonlinear, unless the indicator's is the clearly nonlinear one (a cooling-water
   temperature read right after a sticky valve that its window cannot call at 36 s).
4. **An indicator** (a measured signal of no loop) that leads the loops' cycle (its net
   Granger flow at least ``FLOW_LEADS`` and above every loop's):

   - with no loop named by 1-3, the cycle enters from outside the loops by it (``entry``);
   - with a loop named by its own verdict at a confidence under ``CONFIDENT``, the cycle
     enters from outside instead when the indicator's evidence is stronger than that loop's
     own: its cycle is nonlinear by ``NLI_ENTRY`` (six of its surrogates' standard
     deviations) and more nonlinear than the loop's by ``2 * NLI_MARGIN``, the loop's own
     cycle linear (index at most ``NLI_OUTSIDE``), as a header read right after a square
     load is;
   - a loop called at ``CONFIDENT`` or more whose own cycle trails (net flow below 0) is no
     source against such an indicator either: the cycle enters from outside and the loop
     is *kept* (its call stands, no role: check upstream and its valve);
   - else the loop stays the source and the group is *also fed from outside*
     (``upstream``: check upstream). A loop called at ``CONFIDENT`` or more stays: a flow
     indicator right after its sticky valve, or one that leads it through its own
     measurement's dynamics (a level's integration, a slow transmitter), leads it and is
     more nonlinear than it (issue 37's real record: a net flow of +0.12, an index of 1.6
     against the sticky level loop's 0.8), and is no cause.

   An indicator's lead alone never turns a loop's ``stiction`` into ``propagated``: a called
   loop in a cycle that enters from outside is *kept* (its verdict stands, no role, its
   reason says so) unless the entry is the stronger evidence above.
5. Else no loop is named: none shows evidence of being the source (it may be outside the
   loops read, or not told from this data).

A called outer loop of a declared cascade whose inner loop is a member speaks for the inner
loop's valve (its "valve" is the inner loop): in 1 the inner loop takes its place, and the
outer loop follows. Every other member whose own verdict is ``stiction`` (or whose valve
names it, or that leads the group with its own valve as in 3) follows the source when the
source leads it (Granger gain from the source at least ``COUPLED`` and net flow from it
positive) or its cycle is in step with the source's (coherence at least ``IN_STEP``: one
cycle, carried); a loop whose own window says
``stiction`` at ``CONFIDENT`` or more follows only a source whose evidence is clearly
stronger than its own (:func:`stronger`), and is overridden in 1 only by such a loop. Of
several called loops the source is the best ranked that no other has stronger evidence
than while it carries that other's cycle (of the ``RIVALS`` best ranked). A follower's
reason names that evidence; a called member that follows no source is a source of its own
(two sticky valves at one period) or, in a group with no loop source or clearly trailing
another loop, kept. A declared cascade's outer loop is never a source of its own, nor taken
from its inner loop.

Hysteresis (the gateway's successive rounds): a source named last round stays the source
while it is a member, still has evidence of its own at a lower bar (called ``stiction``, a
per-loop confidence of at least ``HOLD_CONFIDENCE`` or a valve score of half
``SOURCE_SCORE``), and no other member overrides it as in 1.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

from .nonlinearity import NLI_NONLINEAR
from .source import SOURCE_SCORE, MemberEvidence
from .weigh import (
    CONF_MARGIN,
    DIRECTION_SAMPLES,
    FLOW_LEADS,
    FLOW_MARGIN,
    FLOW_NAME,
    NLI_MARGIN,
    VALVE_MARGIN,
    Flow,
    IndicatorEvidence,
    nli_of,
    shaped,
    stronger,
    trailed,
)

__all__ = ["CONFIDENT", "CONF_MARGIN", "COUPLED", "DIRECTION_SAMPLES", "FLOW_LEADS",
           "FLOW_MARGIN", "FLOW_NAME", "HOLD_CONFIDENCE", "IN_STEP", "NLI_ENTRY", "NLI_MARGIN",
           "NLI_OUTSIDE", "VALVE_MARGIN", "Decision", "IndicatorEvidence", "decide",
           "stronger"]

NLI_OUTSIDE = 1.0
"""Thornhill's bound of a linear cycle. A loop called ``stiction`` whose cycle is above it
keeps its place as the source whatever an indicator shows: one read right after a sticky
valve leads the valve's loop and is more nonlinear than it (TEP's cooling water temperatures
after their valves: indices 5.7 against 3.3, 1.9 against 1.5)."""
NLI_ENTRY = 2.0
"""An indicator's index from which its cycle is nonlinear beyond doubt (six standard
deviations of its surrogates): with its lead, stronger evidence than a called loop's own
linear cycle (a header after a square load: 1.9-6.5 on the project's plants; the flow
indicator of issue 37's real record, 1.6 against its sticky level loop's 0.8, is not)."""
COUPLED = 0.05
"""Granger gain from the source from which a member follows it."""
IN_STEP = 0.9
"""Coherence with the source's cycle from which a member carries it (the member bar of
:data:`.groups.MEMBER`): at a historian's sampling Granger both ways is large and its net
flow unreliable (5 samples a cycle: 0.4 each way), one cycle in step is not."""
CONFIDENT = 0.9
"""A loop's own ``stiction`` at this confidence or more is overturned only by a loop named
the source on stronger evidence than its own."""
HOLD_CONFIDENCE = 0.5
RIVALS = 4
"""Called loops compared with each other for the source's place (the best ranked: a group of
hundreds of suspected loops compares a few, not every pair)."""


@dataclasses.dataclass(frozen=True)
class Decision:
    """The source (None: no loop), other sources, which evidence named it, the indicator it
    enters by (``outside``), why each called loop that is not a source follows, the called
    loops kept as they were (``kept``, loop -> why) and the indicator that leads while a loop
    is the source (``upstream``)."""

    source: str | None
    also: tuple[str, ...]
    named_by: tuple[str, ...]
    outside: str | None
    demoted: Mapping[str, str]
    kept: Mapping[str, str] = dataclasses.field(default_factory=dict)
    upstream: str | None = None


def _lead(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence]
          ) -> IndicatorEvidence | None:
    """The indicator that leads the loops' cycle (module doc, 4), or None."""
    measured = [i for i in indicators if i.flow is not None]
    if not measured:
        return None
    lead = max(measured, key=lambda i: i.flow or 0.0)
    loop_flow = max((e.flow for e in ranking if e.flow is not None), default=-1e9)
    if (lead.flow or 0.0) < FLOW_LEADS or (lead.flow or 0.0) <= loop_flow:
        return None
    return lead


def _entry_beats(ind: IndicatorEvidence, e: MemberEvidence) -> bool:
    """Is the indicator's evidence that the cycle enters from outside stronger than called
    loop ``e``'s own (module doc, 4)?"""
    return nli_of(ind) >= NLI_ENTRY and nli_of(e) <= NLI_OUTSIDE and \
        nli_of(ind) >= nli_of(e) + 2.0 * NLI_MARGIN


def _overrides(t: MemberEvidence, s: MemberEvidence, flow: Flow,
               cascades: Mapping[str, str], resolved: bool) -> bool:
    """Does ``t`` take the source's place from called loop ``s`` (module doc, 1)?"""
    if cascades.get(t.loop) == s.loop or t.loop == s.loop:
        return False  # the outer loop of a cascade: its valve is s
    own = t.valve >= SOURCE_SCORE or (nli_of(t) > NLI_NONLINEAR and nli_of(t) > nli_of(s)) \
        or (t.valve >= SOURCE_SCORE / 2 and stronger(t, s, flow, resolved=resolved))
    if (s.confidence or 0.0) >= CONFIDENT and not stronger(t, s, flow, resolved=resolved):
        return False  # a confident call is overturned only by stronger evidence
    return own and flow(t.loop, s.loop) >= FLOW_MARGIN


def _leads(top: MemberEvidence, ranking: Sequence[MemberEvidence],
           indicators: Sequence[IndicatorEvidence], cascades: Mapping[str, str]) -> list[str]:
    """The evidence that names ``top`` by direction (module doc, 3): it leads the group
    (net flow at least ``FLOW_LEADS``, the highest, above every indicator's) and its cycle
    is nonlinear and the most nonlinear (a declared outer loop of ``top``'s cascade aside),
    by ``NLI_MARGIN`` or with a net flow of ``FLOW_NAME``, and a weaker lead is not against a
    valve fit that clears its valve; or it leads by ``FLOW_NAME`` and its valve score
    reaches ``SOURCE_SCORE``."""
    flow = top.flow or 0.0
    if flow < FLOW_LEADS or flow < max(e.flow or 0.0 for e in ranking) or \
            flow <= max((i.flow for i in indicators if i.flow is not None
                         and _against(i, top)), default=-1e9):
        return []
    others = max((nli_of(e) for e in ranking
                  if e is not top and cascades.get(e.loop) != top.loop), default=-1e9)
    if nli_of(top) > NLI_NONLINEAR and nli_of(top) >= others and \
            (flow >= FLOW_NAME or (nli_of(top) >= others + NLI_MARGIN and not _cleared(top))):
        return ["direction", "nonlinearity"]
    return ["direction", "own valve"] if flow >= FLOW_NAME and top.valve >= SOURCE_SCORE \
        else []


def _against(ind: IndicatorEvidence, e: MemberEvidence) -> bool:
    """Does an indicator's lead count against loop ``e`` being named by direction or
    nonlinearity? Not where its window suspects its own valve (``CONFIDENT``) and its cycle
    is nonlinear while the indicator's is not the clearly nonlinear one (:func:`_entry_beats`):
    a signal read after its valve leads it through the loop's own dynamics."""
    return (e.confidence or 0.0) < CONFIDENT or _entry_beats(ind, e)


def _cleared(e: MemberEvidence) -> bool:
    """Does ``e``'s own valve fit clear its valve (fitted, a valve score under half
    ``SOURCE_SCORE``: a sticky valve explains no more of its PV than a linear one)? Then a
    lead under ``FLOW_NAME`` and a nonlinear cycle do not name it: the loop a cycle from
    outside enters first shows both (module doc, 3)."""
    return e.valve_gain is not None and e.valve < SOURCE_SCORE / 2


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
            flow: Flow, cascades: Mapping[str, str], previous: str | None, *,
            resolved: bool, carries: Callable[[MemberEvidence, MemberEvidence], bool]
            ) -> tuple[MemberEvidence | None, list[str], str | None]:
    """(source, named_by, the called loop it overrides): module doc, 1-3 and the hold."""
    top = ranking[0]
    by_name = {e.loop: e for e in ranking}
    # a called outer loop of a cascade speaks for its inner loop's valve, when that is here;
    # a called loop whose cycle clearly trails another loop's is not named by its verdict
    called = list(dict.fromkeys(by_name.get(cascades.get(e.loop, ""), e) for e in ranking
                                if e.called and not trailed(e, ranking, flow)))
    called.sort(key=lambda e: (e.confidence or 0.0) < CONFIDENT)  # confident first, by rank
    source: MemberEvidence | None = None
    named: list[str] = []
    over: str | None = None
    if called:  # the first no other called loop in its cycle has stronger evidence than
        rivals = called[:RIVALS]
        best = next((c for c in rivals if not any(
            stronger(d, c, flow, resolved=resolved) and carries(d, c)
            for d in rivals if d is not c)),
            called[0])
        if top is not best and _overrides(top, best, flow, cascades, resolved):
            source, over = top, best.loop
            named = ["own valve"] if top.valve >= SOURCE_SCORE else ["nonlinearity"]
            named.append("direction")
        else:
            source = best
            named = ["own verdict"] if best.called else \
                ["own verdict of its cascade's outer loop"]
    elif top.valve_named and not _trails(top, [i for i in indicators if _entry_beats(i, top)]):
        source, named = top, ["own valve"]
    elif _leads(top, ranking, indicators, cascades):
        source, named = top, _leads(top, ranking, indicators, cascades)
    elif not resolved and (clear := shaped(ranking, indicators, _against)) is not None:
        source, named = clear, ["nonlinearity"]
    held = next((e for e in ranking if e.loop == previous), None)
    if held is not None and held is not source and _holds(held) and \
            (source is None or not _overrides(source, held, flow, cascades, resolved)):
        source, named, over = held, ["held: named in the last round, its evidence stands"], None
    if source is not None:
        if "direction" not in named and source.flow is not None and source.flow >= FLOW_LEADS \
                and source.flow >= max((e.flow or 0.0) for e in ranking):
            named.append("direction")
        if "nonlinearity" not in named and nli_of(source) > NLI_NONLINEAR and \
                nli_of(source) >= max(nli_of(e) for e in ranking):
            named.append("nonlinearity")
    return source, named, over


def _from_outside(ranking: Sequence[MemberEvidence], ind: IndicatorEvidence,
                  source: MemberEvidence | None) -> Decision:
    """The cycle enters from outside by ``ind`` (module doc, 4): the called loops kept, or
    followers where the entry is the stronger evidence and their call is not confident."""
    demoted: dict[str, str] = {}
    kept: dict[str, str] = {}
    nli = "" if ind.nli is None else f", nonlinearity index {ind.nli:.1f}"
    for e in ranking:
        if not e.called:
            continue
        if source is not None and (e.confidence or 0.0) < CONFIDENT and _entry_beats(ind, e):
            demoted[e.loop] = (f"indicator {ind.name} leads its cycle (Granger net flow "
                               f"{ind.flow or 0.0:+.2f}{nli}, against its own linear cycle): "
                               "the cycle enters from outside the loops")
        else:
            kept[e.loop] = (f"its own window's call stands: the cycle it shares enters from "
                            f"outside by indicator {ind.name} (Granger net flow "
                            f"{ind.flow or 0.0:+.2f}{nli}), which is no evidence against its "
                            "valve: check upstream and its valve")
    return Decision(None, (), ("indicator",), ind.name, demoted, kept)


def decide(ranking: Sequence[MemberEvidence], indicators: Sequence[IndicatorEvidence],
           flow: Flow, granger: Flow, *, cascades: Mapping[str, str],
           previous: str | None = None, coherence: Flow | None = None,
           period: float = DIRECTION_SAMPLES) -> Decision:
    """The group's source from its members' ``ranking`` (best first) and its indicators;
    ``flow(a, b)``: net Granger flow from a to b, ``granger(a, b)``: the gain from a to b,
    ``coherence(a, b)``: of their cycles (measured on demand; None: not measured);
    ``previous``: the source named last round; ``period``: the cycle's, in samples
    (module doc)."""
    lead = _lead(ranking, indicators)
    resolved = period >= DIRECTION_SAMPLES

    def carries(a: MemberEvidence, b: MemberEvidence) -> bool:
        """Does ``b`` carry ``a``'s cycle: led by it, or in step with it?"""
        return (granger(a.loop, b.loop) >= COUPLED and flow(a.loop, b.loop) > 0) or \
            (coherence is not None and coherence(a.loop, b.loop) >= IN_STEP)

    source, named, over = _choose(ranking, indicators, flow, cascades, previous,
                                   resolved=resolved, carries=carries)
    by_verdict = bool(named) and named[0].startswith(("own verdict", "held"))
    if lead is not None and (source is None or (
            over is None and by_verdict and _entry_beats(lead, source) and (
                (source.confidence or 0.0) < CONFIDENT or (source.flow or 0.0) < 0))):
        return _from_outside(ranking, lead, source)
    demoted: dict[str, str] = {}
    kept: dict[str, str] = {}
    also: list[str] = []
    for e in ranking:
        if e is source or not (e.called or e.valve_named or (
                (e.flow or 0.0) >= FLOW_NAME and e.valve >= SOURCE_SCORE
                and "own valve" in _leads(e, ranking, indicators, cascades))):
            continue
        if source is None:
            if e.called:
                kept[e.loop] = ("its own window's call stands: no loop of the group shows "
                                "evidence of being the source of the cycle it shares, and its "
                                f"own cycle trails another loop's (Granger net flow "
                                f"{e.flow or 0.0:+.2f} to the group)")
            continue
        if cascades.get(e.loop) == source.loop:
            demoted[e.loop] = (f"its valve is {source.loop}'s: the outer loop of a cascade whose "
                               "inner loop is the source")
            continue
        why = _follows(source, e, named=named, over=over, flow=flow, granger=granger,
                       coherence=coherence, resolved=resolved)
        if why is not None:
            demoted[e.loop] = why
        elif e.called and trailed(e, ranking, flow):
            kept[e.loop] = (f"its own window's call stands: its cycle trails another loop's "
                            f"(Granger net flow {e.flow or 0.0:+.2f} to the group) and no "
                            f"evidence stronger than its own makes it follow {source.loop}")
        elif e.called or e.loop not in cascades:
            also.append(e.loop)
    return Decision(None if source is None else source.loop, tuple(also), tuple(named), None,
                    demoted, kept, None if source is None or lead is None else lead.name)


def _follows(source: MemberEvidence, e: MemberEvidence, *, named: Sequence[str],
             over: str | None, flow: Flow, granger: Flow, coherence: Flow | None,
             resolved: bool) -> str | None:
    """Why called (or valve-named) member ``e`` follows ``source`` (module doc), or None
    when it does not."""
    net = flow(source.loop, e.loop)
    if e.loop == over:
        return (f"{source.loop} leads its cycle (Granger net flow {net:+.2f}; {source.loop} is "
                f"named by {', '.join(named)})")
    if e.called and (e.confidence or 0.0) >= CONFIDENT and \
            not stronger(source, e, flow, resolved=resolved):
        return None  # a confident call is overturned only by stronger evidence
    if granger(source.loop, e.loop) >= COUPLED and net > 0:
        return f"{source.loop} leads its cycle (Granger net flow {net:+.2f})"
    coh = 0.0 if coherence is None else coherence(source.loop, e.loop)
    if coh >= IN_STEP:
        return f"its cycle is in step with {source.loop}'s (coherence {coh:.2f})"
    return None
