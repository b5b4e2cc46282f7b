"""Evidence weighed by its strength (issue 37, item 1): a loop whose own window says
``stiction`` at high confidence stays ``stiction`` unless another loop is named the source
on stronger evidence; an indicator's lead alone only says "also fed from outside"; a source
whose own window says ``no_stiction`` is told what its evidence points to instead."""

from __future__ import annotations

import dataclasses
import functools

import pytest

from stiction import Assessment, Verdict, analyze
from stiction.plant import analyze_plant
from stiction.plant.decide import CONFIDENT, IndicatorEvidence, decide
from stiction.plant.source import MemberEvidence
from stiction.plant.story import group_reason, instead
from stiction.scenarios.plant import Indicator, Link, PlantLoop, PlantScenario, simulate_plants


def _loop(name: str, **kw: float | str | None) -> MemberEvidence:
    base: dict[str, object] = {"loop": name, "strength": 0.5, "valve_gain": 0.0, "kano": 0.0,
                               "episodes": 0, "confidence": 0.2, "harmonics": 0.0,
                               "verdict": "no_stiction", "flow": 0.0, "nli": 0.5}
    base.update(kw)
    return MemberEvidence(**base)  # type: ignore[arg-type]


def _none(a: str, b: str) -> float:
    return 0.0


# issue 37's real record, its evidence as the report gave it: the sticky level loop ranked
# first (score 1.31 against 0.34), its own window stiction at 0.94, its cycle index 0.8, 80 %
# of its power in the cycle; a flow indicator leads (Granger +0.12) with an index of 1.6
LEVEL = _loop("LIC1", strength=0.8, confidence=0.94, verdict="stiction", flow=0.05, nli=0.8,
              valve_gain=0.19)
OTHERS = [_loop("FIC2", confidence=0.3, flow=-0.02, nli=0.5), _loop("TIC3", flow=-0.03, nli=0.4)]
FLOW_INDICATOR = IndicatorEvidence("FI4", 0.7, flow=0.12, nli=1.6)


def test_a_confident_call_stays_the_source_when_an_indicator_leads_it() -> None:
    assert LEVEL.score == pytest.approx(1.31, abs=0.01)
    d = decide([LEVEL, *OTHERS], [FLOW_INDICATOR], _none, _none, cascades={})
    assert d.source == "LIC1" and d.outside is None and d.named_by[0] == "own verdict"
    assert d.upstream == "FI4" and not d.demoted and not d.kept
    reason = group_reason(6497.0, 3, (LEVEL, *OTHERS), (FLOW_INDICATOR,), d)
    assert "also fed from outside? indicator FI4 leads the cycle (Granger net flow +0.12, " \
           "nonlinearity index 1.6)" in reason and "check upstream" in reason
    # however strongly the indicator leads and however nonlinear its cycle: a lead is no
    # evidence against a confident call
    strong = dataclasses.replace(FLOW_INDICATOR, flow=0.9, nli=6.0)
    d = decide([LEVEL, *OTHERS], [strong], _none, _none, cascades={})
    assert d.source == "LIC1" and d.upstream == "FI4"


def test_a_lead_alone_never_makes_a_called_loop_propagated() -> None:
    """Below ``CONFIDENT`` too: a lead whose cycle is not clearly more nonlinear than the
    loop's keeps the loop the source; one that is (a header after a square load) makes the
    cycle enter from outside and the loop a follower."""
    called = dataclasses.replace(LEVEL, confidence=CONFIDENT - 0.02, nli=0.4)
    d = decide([called, *OTHERS], [FLOW_INDICATOR], _none, _none, cascades={})
    assert d.source == "LIC1" and d.upstream == "FI4" and not d.demoted
    square = dataclasses.replace(FLOW_INDICATOR, flow=0.3, nli=4.5)
    d = decide([called, *OTHERS], [square], _none, _none, cascades={})
    assert d.source is None and d.outside == "FI4" and list(d.demoted) == ["LIC1"]
    assert d.demoted["LIC1"].startswith("indicator FI4 leads its cycle")


def test_a_confident_follower_is_overturned_only_by_a_stronger_source() -> None:
    """TIC201 of sticky-feeds-two at a historian's 30 s: its own window says stiction at
    0.91, its cycle in step with FIC101's (coherence 0.98), Granger both ways about 0.4 (no
    net lead); FIC101 has stronger evidence: TIC201 follows. Against a source no stronger
    than itself it stays a source of its own."""
    fic = _loop("FIC101", confidence=0.95, verdict="stiction", flow=0.22, nli=3.7)
    tic = _loop("TIC201", confidence=0.91, verdict="stiction", flow=0.11, nli=1.0)
    in_step = {("FIC101", "TIC201"): 0.98}

    def coherence(a: str, b: str) -> float:
        return in_step.get((a, b), 0.0)

    d = decide([fic, tic], [], _none, _none, cascades={}, coherence=coherence)
    assert d.source == "FIC101" and d.also == () and "in step with FIC101's" in \
        d.demoted["TIC201"]
    weak = dataclasses.replace(fic, flow=0.0, nli=1.0)
    d = decide([weak, tic], [], _none, _none, cascades={}, coherence=coherence)
    assert d.source in ("FIC101", "TIC201") and not d.demoted and len(d.also) == 1


@pytest.mark.parametrize(("evidence", "says"), [
    ({"valve_gain": 0.5}, "a step test in manual tells the two apart"),
    ({"nli": 3.0}, "another nonlinearity at this loop than its valve"),
])
def test_a_source_whose_own_window_says_no_stiction_is_told_what_else(
        evidence: dict[str, float], says: str) -> None:
    """The real record's second group: a pressure loop named on Granger +0.47 and an index
    of 3.0 (or a valve fit) while its own window says no_stiction at 0.39."""
    src = _loop("PIC1", confidence=0.39, flow=0.47, **evidence)
    d = decide([src, *OTHERS], [], _none, _none, cascades={})
    assert d.source == "PIC1"
    reason = group_reason(415.0, 3, (src, *OTHERS), (), d)
    assert "its own window says no_stiction" in reason and says in reason


def test_a_linear_cycle_at_a_source_points_to_tuning_or_a_disturbance() -> None:
    said = instead(_loop("PIC1", confidence=0.39, flow=0.47, nli=0.3))
    assert "points to its tuning (a controller gain near the loop's limit) or a " \
           "disturbance entering at this loop, not to its valve" in said


# ------------------------------------------------ a realistic indicator, simulated


@functools.cache
def _sensor_lag() -> tuple[dict[str, tuple[object, object]], dict[str, object], float]:
    """Issue 37's real record, simulated: a sticky level valve (LIC101, fs 8 %) whose level
    transmitter lags 60 s, its 1.6 h cycle reaching a flow and a pressure loop, and LI105 (a
    second level gauge) reading the level itself, before that lag. Exported at 20 s, 8 h, as
    the record was. LI105 leads LIC101's PV through the transmitter's lag (Granger +0.6)
    and its cycle is about as linear as the loop's (indices 0.7 and 0.8, under 1; a slow
    level cycle read through lags is near sinusoidal)."""
    lic = PlantLoop("LIC101", kp=0.01, integrating=True, theta=5.0, kc=0.5, ti=2400.0,
                    fs=0.08, fd=0.04, k=1.99, load_sd=0.001, sp_step=2.0, sensor_tau=60.0)
    fic = PlantLoop("FIC201", kp=1.0, tau=8.0, theta=2.0, kc=0.5, ti=20.0)
    pic = PlantLoop("PIC301", kp=1.0, tau=40.0, theta=4.0, kc=1.0, ti=60.0)
    sc = PlantScenario("lagged", (lic, fic, pic), (Link("LIC101", "FIC201", gain=0.8, tau=30.0),
                                                   Link("LIC101", "PIC301", gain=0.6, tau=20.0)),
                       indicators=(Indicator("LI105", "LIC101", signal="process", tau=1.0),))
    (rec,) = simulate_plants([sc], duration=28800.0, sample=20, seed=3)
    return ({n: (rec.op[n], rec.pv[n]) for n in rec.op}, dict(rec.indicators), rec.ts)


def test_an_indicator_leading_through_the_loops_own_sensor_lag_is_no_cause() -> None:
    """The sticky loop's own window says stiction (0.96); LI105 leads it through its own
    transmitter's lag with a cycle no more nonlinear than its own. On 5c94178 the cycle
    "entered from outside" by LI105 and LIC101 was ``propagated`` (the real record's
    story); here LIC101 is the source, the group also fed from outside (check upstream)."""
    loops, indicators, ts = _sensor_lag()
    proc = {"LIC101": "integrating"}
    own: dict[str, Assessment] = {
        n: analyze(op, pv, ts=ts, process=proc.get(n, "self-regulating"))  # type: ignore[arg-type]
        for n, (op, pv) in loops.items()}
    assert own["LIC101"].verdict == Verdict.STICTION and (own["LIC101"].confidence or 0) > 0.93
    view = analyze_plant(loops, ts=ts, indicators=indicators, assessments=own,  # type: ignore[arg-type]
                         processes=proc)
    (g,) = [g for g in view.groups if "LIC101" in g.loops]
    assert set(g.loops) == {"LIC101", "FIC201", "PIC301"}
    li = next(i for i in g.indicators if i.name == "LI105")
    assert (li.flow or 0.0) > 0.4 and (li.flow or 0.0) > max(e.flow or 0.0 for e in g.ranking) + 0.3
    assert g.source == "LIC101" and g.entry is None and g.upstream == "LI105"
    assert "check upstream" in g.reason
    assert view.roles["LIC101"].role == "source"
    after = view.apply(own)
    assert after["LIC101"].verdict == Verdict.STICTION
    # no other loop reads stiction (a follower its own window calls reads propagated)
    assert [n for n in loops if after[n].verdict == Verdict.STICTION] == ["LIC101"]
    assert all(view.roles[n].role == "follower" for n in ("FIC201", "PIC301"))


def test_a_second_valve_that_leads_with_its_own_evidence_is_a_source_of_its_own() -> None:
    """Two sticky valves whose cycles merged into one group (the benchmark's two-3): one
    called stiction at 0.88, the other's own window says no_stiction at 0.2 while a sticky
    valve explains its PV (0.93) and it leads the group (+1.38); they do not drive each
    other. Both are sources."""
    a = _loop("FIC1a", confidence=0.88, verdict="stiction", valve_gain=0.54, flow=0.0,
              nli=2.1)
    b = _loop("FIC1b", confidence=0.2, valve_gain=0.93, flow=1.38, nli=1.8)
    d = decide([b, a, *OTHERS], [], _none, _none, cascades={})
    assert {d.source, *d.also} == {"FIC1a", "FIC1b"} and not d.demoted


@pytest.mark.parametrize(("lead", "period", "source"), [
    (0.3, 11.5, "FIC1"),  # resolved: a lead of 0.1 counts
    (0.2, 2.7, "LIC2"),  # 2.7 samples a period: a lead under 0.3 is noise there
    (0.45, 2.7, "FIC1"),  # ... a lead of 0.3 or more is not
])
def test_a_confident_call_gives_way_to_a_loop_with_stronger_evidence_that_leads_it(
        lead: float, period: float, source: str) -> None:
    """The benchmark's sticky-5 at 60 s: a level loop called stiction at 0.92 with nothing
    else for it; the sticky flow loop (its window 0.82) has a valve fit (0.19) and leads it:
    the flow loop is the source, the level follows; unless the cycle is not resolved and
    the lead is within the noise of a net flow there."""
    level = _loop("LIC2", confidence=0.92, verdict="stiction", flow=-0.05, nli=0.3)
    flow_loop = _loop("FIC1", confidence=0.82, verdict="undetermined", valve_gain=0.19,
                      flow=0.18, nli=0.7)
    leads = {("FIC1", "LIC2"): lead}

    def flow(a: str, b: str) -> float:
        return leads.get((a, b), -leads.get((b, a), 0.0))

    d = decide([flow_loop, level, *OTHERS], [], flow, lambda a, b: max(flow(a, b), 0.0),
               cascades={}, period=period)
    assert d.source == source and ("LIC2" in d.demoted) == (source == "FIC1")
