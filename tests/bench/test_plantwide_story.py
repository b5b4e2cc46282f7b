"""One story per loop over the plant-wide benchmark's runs (issue 29): no loop is a
``follower`` and ``stiction`` at once, in the plant view, ``stiction plant``'s JSON and
text (:func:`bench.accuracy.plantwide.stories`, which the benchmark counts for every run it makes)
and in the gateway's registers and metrics.

The runs: one plant of every kind the benchmark draws (a seed it does not use), at the
gateway's 4 s and as a historian's 60 s export, every loop called ``stiction`` by its own
window (the worst case: every follower suspected)."""

from __future__ import annotations

import dataclasses
import functools

import pytest
from prometheus_client import CollectorRegistry

from bench.accuracy._plantwide_data import cascades, processes, resampled
from bench.accuracy.plantwide import stories
from gateway.core.plant import PlantTracker
from gateway.core.store import ResultStore
from gateway.outputs.prometheus import StoreCollector
from gateway.wire.results import ROLES, VERDICT_CODES, decode_block, result_block, verdict_code
from stiction import Assessment, Verdict, analyze
from stiction.plant import PlantAssessment, analyze_plant
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import PLANT_KINDS, plant_scenarios


@functools.cache
def _runs() -> list[tuple[str, PlantRecord]]:
    scenarios = [plant_scenarios(kind, 1, seed=29)[0] for kind in PLANT_KINDS]
    recs = simulate_plants(scenarios, duration=7200.0, sample=4, seed=29)
    return [(f"{k} {ts:g} s", rec if ts == 4 else resampled(rec, ts))
            for k, rec0 in zip(PLANT_KINDS, recs, strict=True) for ts, rec in
            ((4.0, rec0), (60.0, rec0))]


def _suspected(rec: PlantRecord) -> dict[str, Assessment]:
    proc = processes(rec)
    return {n: dataclasses.replace(a, verdict=Verdict.STICTION, confidence=0.9)
            for n in rec.op
            for a in [analyze(rec.op[n], rec.pv[n], ts=rec.ts, process=proc[n])]}


def _store(pa: PlantAssessment, before: dict[str, Assessment]) -> ResultStore:
    """The gateway's store after a round with this plant view (as PlantTracker.round
    publishes it)."""
    names = list(before)
    store = ResultStore(names)
    view, _events = PlantTracker().update([(pa, names)])
    store.set_plant(view)
    after = pa.apply(before)
    for i, n in enumerate(names):
        store.set_result(i, after[n], t=0.0, window_fill=1.0, samples=1)
    return store


@pytest.mark.parametrize("index", range(2 * len(PLANT_KINDS)))
def test_no_loop_is_a_follower_and_stiction_in_any_output(index: int) -> None:
    label, rec = _runs()[index]
    before = _suspected(rec)
    pa = analyze_plant({n: (rec.op[n], rec.pv[n]) for n in rec.op}, ts=rec.ts,
                       indicators=rec.indicators, assessments=before,
                       processes=processes(rec), cascades=cascades(rec))
    after = pa.apply(before)
    assert stories(pa, after) == 0, label
    store = _store(pa, before)
    registry = CollectorRegistry()
    registry.register(StoreCollector(store))
    followers = 0
    for i, name in enumerate(store.loops):
        res = store.results[i]
        assert res is not None
        block = decode_block(result_block(res, code=verdict_code(res),
                                          plant=store.plant_registers(i)))
        follower = ROLES[int(block["plant_role"])] == "follower"
        followers += follower
        assert not (follower and block["code"] == VERDICT_CODES["stiction"]), (label, name)
        called = registry.get_sample_value("stiction_loop_verdict",
                                           {"loop": name, "verdict": "stiction"})
        role = registry.get_sample_value("stiction_loop_plant_role",
                                         {"loop": name, "role": "follower"})
        assert not (called == 1.0 and role == 1.0), (label, name)
    if rec.scenario.sources and pa.groups:
        assert followers, label  # the check saw followers, every one called stiction before
