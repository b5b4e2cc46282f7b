"""The plant-wide view on hand-made plants (stiction.scenarios.plants.NAMED_PLANTS): which
loops share an oscillation, which is its source, and what becomes of the followers."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from plant_fixtures import plant_records

from stiction import Assessment, Evidence, ParameterError, Verdict, analyze
from stiction.plant import PlantAssessment, analyze_plant
from stiction.scenarios.plant import PlantRecord


def _processes(rec: PlantRecord) -> dict[str, str]:
    return {lp.name: "integrating" if lp.integrating else "self-regulating"
            for lp in rec.scenario.loops}


@functools.cache
def _view(name: str) -> tuple[PlantRecord, dict[str, Assessment], PlantAssessment]:
    rec = plant_records()[name]
    proc = _processes(rec)
    before = {n: analyze(rec.op[n], rec.pv[n], ts=rec.ts, process=proc[n]) for n in rec.op}
    view = analyze_plant({n: (rec.op[n], rec.pv[n]) for n in rec.op}, ts=rec.ts,
                         indicators=rec.indicators, assessments=before, processes=proc)
    return rec, before, view


def test_a_sticky_valve_and_its_followers_form_one_group_with_the_valve_as_source() -> None:
    _rec, before, view = _view("sticky-feeds-two")
    (g,) = [g for g in view.groups if "FIC101" in g.loops]
    assert {"FIC101", "TIC201", "LIC301"} <= set(g.loops)
    assert "TI205" in {m.name for m in g.members if m.kind == "indicator"}
    assert g.source == "FIC101" and g.ranking[0].loop == "FIC101"
    assert 140 < g.period_s < 180
    # its own window: at least undetermined with the valve evidence for (the named source)
    assert before["FIC101"].verdict in (Verdict.STICTION, Verdict.UNDETERMINED)
    assert view.roles["FIC101"].role == "source"
    assert view.roles["TIC201"].role == view.roles["LIC301"].role == "follower"
    assert view.roles["TIC201"].source == "FIC101"
    assert "FIC101 is the source of the" in g.reason and "sticky valve explains" in g.reason


def test_a_follower_called_stiction_becomes_propagated_and_the_source_keeps_its_size() -> None:
    _rec, before, view = _view("sticky-feeds-two")
    # whatever the per-loop tests said of the follower, say they called it sticky
    sized = dataclasses.replace(before["TIC201"], verdict=Verdict.STICTION, fd=0.02, fs=0.03,
                                fd_op=2.0, fs_op=3.0, cycles_used=5, confidence=0.91)
    after = view.apply({**before, "TIC201": sized})
    t = after["TIC201"]
    assert t.verdict == Verdict.PROPAGATED
    assert (t.fd, t.fs, t.fd_op, t.fs_op, t.cycles_used) == (None, None, None, None, 0)
    assert "its source is FIC101" in t.reason and "cycle of 1" in t.reason
    assert t.evidence == sized.evidence  # every test's value and vote kept
    assert after["FIC101"] == before["FIC101"]  # the source keeps its verdict and size
    alone = [n for n, r in view.roles.items() if r.role is None]
    assert all(after[n] == before[n] for n in alone)  # (tested apart below, too)


def test_a_square_cycle_from_outside_has_no_loop_source() -> None:
    _rec, before, view = _view("header-square")
    (g,) = [g for g in view.groups if "TIC201" in g.loops]
    assert abs(g.period_s - 600.0) < 40.0
    assert {"TIC201", "PIC401", "FIC102"} <= set(g.loops)
    assert g.source is None and g.external
    assert "PI_STEAM" in {m.name for m in g.members}
    assert "no loop analysed here is the source" in g.reason
    called = {n: dataclasses.replace(a, verdict=Verdict.STICTION) for n, a in before.items()}
    after = view.apply(called)
    for name in ("TIC201", "PIC401", "FIC102"):
        assert after[name].verdict == Verdict.PROPAGATED
        assert "its source is no loop analysed here" in after[name].reason


def test_two_sticky_valves_at_two_periods_are_two_groups() -> None:
    _rec, _before, view = _view("two-sources")
    by_top = {g.ranking[0].loop: g for g in view.groups}
    assert {"FIC101", "FIC501"} <= set(by_top)
    assert by_top["FIC501"].period_s > 2.0 * by_top["FIC101"].period_s
    assert "TIC601" in by_top["FIC501"].loops and "TIC601" not in by_top["FIC101"].loops


def test_loops_sharing_nothing_are_left_as_they_were() -> None:
    rng = np.random.default_rng(5)
    loops = {f"L{i}": (50 + np.cumsum(rng.normal(0, 0.2, 3000)), 50 + rng.normal(0, 1, 3000))
             for i in range(4)}
    before = {n: analyze(op, pv, ts=1.0) for n, (op, pv) in loops.items()}
    view = analyze_plant(loops, ts=1.0, assessments=before)
    assert view.groups == ()
    assert all(r.role is None and r.group is None for r in view.roles.values())
    assert view.apply(before) == before


def test_without_assessments_the_ranking_stands_but_no_source_is_named() -> None:
    rec = _view("sticky-feeds-two")[0]
    view = analyze_plant({n: (rec.op[n], rec.pv[n]) for n in rec.op}, ts=rec.ts,
                         processes=_processes(rec))
    (g,) = [g for g in view.groups if "FIC101" in g.loops]
    assert g.ranking[0].loop == "FIC101" and g.source is None


def test_a_declared_cascade_names_the_inner_loop() -> None:
    rec, before, _v = _view("sticky-feeds-two")
    # declare TIC201 the outer loop of FIC101: TIC201 on top yields to its inner loop
    fake = {**before, "TIC201": dataclasses.replace(before["TIC201"], confidence=0.99)}
    view = analyze_plant({n: (rec.op[n], rec.pv[n]) for n in rec.op}, ts=rec.ts,
                         assessments=fake, processes=_processes(rec),
                         cascades={"TIC201": "FIC101"})
    (g,) = [g for g in view.groups if "FIC101" in g.loops]
    assert g.ranking[0].loop == "FIC101"


def test_bad_input_is_named() -> None:
    op = np.zeros(100)
    with pytest.raises(ParameterError, match=r"loops\['B'\] OP.*100 samples"):
        analyze_plant({"A": (op, op), "B": (np.zeros(99), op)}, ts=1.0)
    with pytest.raises(ParameterError, match="ts"):
        analyze_plant({"A": (op, op)}, ts=0.0)
    with pytest.raises(ParameterError, match=r"indicators\['X'\]"):
        analyze_plant({"A": (op, op)}, ts=1.0, indicators={"X": [[1.0]]})
    assert analyze_plant({}, ts=1.0).groups == ()


def test_gaps_and_flat_signals_do_not_break_it() -> None:
    rec, before, _v = _view("sticky-feeds-two")
    loops = {n: (rec.op[n].copy(), rec.pv[n].copy()) for n in rec.op}
    loops["TIC201"][1][100:130] = np.nan
    loops["PIC401"] = (np.full(rec.op["PIC401"].size, 50.0), rec.pv["PIC401"])
    view = analyze_plant(loops, ts=rec.ts, assessments=before, processes=_processes(rec))
    assert any(g.source == "FIC101" for g in view.groups)


def test_evidence_is_kept_when_a_verdict_is_propagated() -> None:
    e = (Evidence("si_op", 0.8, 1, "OP half cycles fit a triangle"),)
    a = Assessment(Verdict.STICTION, "stiction", evidence=e, confidence=0.9)
    assert a.to_dict()["evidence"][0]["test"] == "si_op"
    assert Assessment.from_dict({**a.to_dict(), "verdict": "propagated"}).verdict == \
        Verdict.PROPAGATED


def test_two_independent_sticky_valves_at_one_period_are_both_sources() -> None:
    """Two flow loops with the same sticky valve on one PLC cycle at one period: a shared
    period cannot tell them from source and follower, their own valve evidence can; neither
    is called propagated (the fleet's plant-a, tests/deploy/test_fleet_live.py)."""
    from stiction import analyze  # noqa: PLC0415
    from stiction.scenarios.named import scenario, simulate  # noqa: PLC0415

    runs = {n: simulate(scenario("table4-case2"), noise=0.02, seed=s)
            for n, s in (("FIC101", 7), ("FIC102", 8))}
    loops = {n: (r.op, r.pv) for n, r in runs.items()}
    before = {n: analyze(op, pv, ts=1.0) for n, (op, pv) in loops.items()}
    assert all(a.verdict == Verdict.STICTION for a in before.values()), before
    view = analyze_plant(loops, ts=1.0, assessments=before)
    after = view.apply(before)
    for n in loops:
        assert after[n] == before[n]
        if view.roles[n].group is not None:
            assert view.roles[n].role == "source" and view.roles[n].source == n
