"""The gateway's plant-wide step (issue 21, item 3), in memory: a round over the loops of
one poll interval, the followers' verdicts, the store's plant view and registers, the log
lines, stable group numbers, the jobs' windows, and the ``plant`` settings through
check-config and reload."""

from __future__ import annotations

import asyncio
import logging
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from memory_harness import mconfig, mloop
from plant_fixtures import loop_group, plant_records

from gateway.cli import main
from gateway.config import PlantSettings, load_config, parse_config
from gateway.core.plant import PlantTracker, plant_jobs
from gateway.core.plantview import PlantGroup, PlantView
from gateway.core.points import Quality
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup
from gateway.errors import ConfigError
from gateway.inputs.memory import memory_device
from gateway.runtime.gateway import Gateway
from gateway.runtime.scheduler import AnalysisScheduler
from gateway.wire.results import decode_block, result_block, verdict_code
from stiction import Assessment, Verdict
from stiction.plant import Group, LoopRole, Member, PlantAssessment

SUSPICIOUS = "plant_fake_analyze:analyze"


_group = loop_group  # (tests/support/plant_fixtures.py)


def _round(groups: list[LoopGroup], store: ResultStore, analyze: str,
           plant: PlantSettings) -> AnalysisScheduler:
    async def go() -> AnalysisScheduler:
        sched = AnalysisScheduler(groups, store, interval_wall_s=1e9, analyze=analyze,
                                  executor=lambda: ThreadPoolExecutor(2), plant=plant)
        await sched.start()
        try:
            await sched.run_round()
        finally:
            await sched.stop()
        return sched

    return asyncio.run(go())


def _sticky_plant() -> tuple[list[LoopGroup], ResultStore]:
    rec = plant_records()["sticky-feeds-two"]
    proc = {lp.name: "integrating" if lp.integrating else "self-regulating"
            for lp in rec.scenario.loops}
    group = _group({n: (rec.op[n], rec.pv[n]) for n in rec.op}, rec.ts, proc)
    return [group], ResultStore(group.loops)


def test_a_round_makes_the_followers_propagated_and_names_the_source(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    groups, store = _sticky_plant()
    _round(groups, store, SUSPICIOUS, PlantSettings())
    verdicts = {n: store.verdict_name(i) for n, i in store.index.items()}
    assert verdicts["FIC101"] == "stiction"
    assert verdicts["TIC201"] == verdicts["LIC301"] == "propagated"
    (g,) = [g for g in store.plant.groups if "FIC101" in g.loops]
    assert g.source == "FIC101" and g.number == 1 and 140 < g.period_s < 180
    assert store.plant.of("TIC201") == (1, "follower", "FIC101")
    assert store.plant_registers(store.index["FIC101"]) == (1, 1, 1)
    i = store.index["LIC301"]
    block = decode_block(result_block(store.results[i], code=verdict_code(store.results[i]),
                                      plant=store.plant_registers(i)))
    assert (block["code"], block["plant_group"], block["plant_role"],
            block["plant_source"]) == (10, 1, 2, 1)
    reason = store.results[i].assessment.reason
    assert "its source is FIC101" in reason
    plant_lines = [r.getMessage() for r in caplog.records if r.name == "gateway.plant"]
    (line,) = [ln for ln in plant_lines if "FIC101" in ln]  # one line per group
    assert line.startswith("plant group 1 appeared: period 1") and "source FIC101" in line
    assert all("appeared" in ln for ln in plant_lines)
    # the same plant with the step off: every suspect stays a suspect
    groups, off = _sticky_plant()
    _round(groups, off, SUSPICIOUS, PlantSettings(enabled=False))
    assert off.verdict_name(off.index["TIC201"]) == "stiction"
    assert off.plant.groups == ()


def test_without_a_group_the_per_loop_verdicts_are_unchanged() -> None:
    rng = np.random.default_rng(5)
    loops = {f"L{i}": (50 + np.cumsum(rng.normal(0, 0.2, 1200)), 50 + rng.normal(0, 1, 1200))
             for i in range(4)}
    stores = []
    for enabled in (True, False):
        group = _group(loops, 1.0, {})
        store = ResultStore(group.loops)
        _round([group], store, "stiction:analyze", PlantSettings(enabled=enabled))
        stores.append(store)
    on, off = stores
    assert on.plant.groups == ()
    assert [r.assessment for r in on.results] == [r.assessment for r in off.results]
    assert all(on.plant_registers(i) == (0, 0, 0) for i in range(4))


def _pa(*groups: tuple[float, str | None, tuple[str, ...]]) -> PlantAssessment:
    gs = tuple(Group(k + 1, period, tuple(Member(n, "loop", 0.5) for n in loops), (), src, "")
               for k, (period, src, loops) in enumerate(groups))
    roles = {n: LoopRole(n, g.number, "source" if n == g.source else "follower", g.source)
             for g in gs for n in g.loops}
    return PlantAssessment(gs, roles)


def test_groups_keep_their_number_and_each_change_is_one_line() -> None:
    t = PlantTracker()
    view, events = t.update([(_pa((150.0, "A", ("A", "B", "C")), (600.0, None, ("D", "E"))),
                              ())])
    assert [g.number for g in view.groups] == [1, 2]
    assert view.of("B") == (1, "follower", "A") and view.of("D") == (2, "follower", None)
    assert len(events) == 2 and all("appeared" in e for e in events)
    # the short cycle's group loses C and its source moves; the long one ends; a new one
    view, events = t.update([(_pa((155.0, "B", ("A", "B")), (40.0, "X", ("X", "Y"))), ())])
    # (a number that ends is free from the next round on)
    assert {g.loops: g.number for g in view.groups} == {("A", "B"): 1, ("X", "Y"): 3}
    assert sorted(events) == sorted([
        "plant group 1: source B (was A), period 155 s, 2 loops",
        "plant group 3 appeared: period 40 s, source X, 2 loops: X, Y",
        "plant group 2 ended (period 600 s, source none among the loops, 2 loops)"])
    assert view.changes["group_appeared"] == 3 and view.changes["group_ended"] == 1
    assert view.changes["source"] == 1
    view, events = t.update([(_pa((155.0, "B", ("A", "B"))), ())])
    assert events == ["plant group 3 ended (period 40 s, source X, 2 loops)"]
    view, events = t.update([(_pa((155.0, "B", ("A", "B")), (90.0, "Q", ("Q", "R"))), ())])
    assert view.of("R") == (2, "follower", "Q")  # the lowest free number
    assert t.update([(_pa((155.0, "B", ("B", "A")), (90.0, "Q", ("Q", "R"))), ())])[1] == []


def test_a_job_holds_one_time_base_averaged_down() -> None:
    rng = np.random.default_rng(1)
    sig = {f"A{i}": (rng.normal(size=3000), rng.normal(size=3000)) for i in range(3)}
    a = _group(sig, 1.0, {}, "p1")
    b = _group({"B0": sig["A0"]}, 1.0, {}, "p2", first_row=3)  # another device, same base
    b.bank.quality[-10:, 0] = Quality.BAD  # the newest 10 samples of B0: gaps
    c = _group({"C0": sig["A1"], "C1": sig["A2"]}, 5.0, {}, "p3", first_row=4)
    d = _group({"D0": sig["A1"], "D1": sig["A2"]}, 1.0, {}, "p4", first_row=6, size=1000)
    ok = Assessment(Verdict.NOT_OSCILLATING, "")
    jobs = plant_jobs([a, b, c, d], dict.fromkeys(range(8), ok), max_samples=1000)
    assert [(j.ts, j.names) for j in jobs] == [(1.0, ("D0", "D1")),
                                               (3.0, ("A0", "A1", "A2", "B0")),
                                               (15.0, ("C0", "C1"))]
    j = jobs[1]
    assert j.op.shape == (4, 1000) and j.op.dtype == np.float32
    np.testing.assert_allclose(j.op[0], sig["A0"][0].reshape(-1, 3).mean(axis=1), atol=1e-6)
    # the newest 10 samples bad: the last three blocks of three are gaps; the block before
    # holds one bad sample and is the mean of its two good ones
    assert np.isnan(j.op[3, -3:]).all() and np.isfinite(j.op[3, :-3]).all()
    assert j.op[3, -4] == pytest.approx(float(sig["A0"][0][-12:-10].mean()), abs=1e-6)
    assert j.rows == (0, 1, 2, 3) and jobs[2].rows == (4, 5)
    # loops not assessed this round take no part; a time base with one loop has no job
    assert plant_jobs([a, b], {0: ok, 3: ok}, max_samples=5000)[0].names == ("A0", "B0")
    assert plant_jobs([a], {0: ok}, max_samples=5000) == []


def test_a_view_maps_loops_to_numbers_roles_and_source_indexes() -> None:
    store = ResultStore(["S", "F", "Z"])
    seen: list[int] = []
    store.subscribe(seen.append)
    store.set_plant(PlantView((PlantGroup(7, 90.0, "S", ("S", "F")),),
                              {"S": (7, "source"), "F": (7, "follower")}))
    assert sorted(seen) == [0, 1]  # Z did not change
    assert [store.plant_registers(i) for i in range(3)] == [(7, 1, 1), (7, 2, 1), (0, 0, 0)]


# ------------------------------------------------------------------ settings


def _plant_cfg(tmp_path: Path, plant: dict[str, Any] | None, name: str = "gw.yaml") -> Path:
    cfg = mconfig([memory_device("plc", [[50.0, 20.0]], poll_interval_s=0.05, repeat=True)],
                  [mloop("A", "plc", 0, 0)], plant=plant)
    if plant is None:
        del cfg["plant"]
    path = tmp_path / name
    path.write_text(yaml.safe_dump(cfg))
    return path


def test_plant_settings_default_on_and_are_checked(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert load_config(_plant_cfg(tmp_path, None)).plant == PlantSettings(True, 1024)
    off = load_config(_plant_cfg(tmp_path, {"enabled": False, "max_samples": 4096}))
    assert off.plant == PlantSettings(False, 4096)
    bad = _plant_cfg(tmp_path, {"enabled": "yes", "max_samples": 10, "colour": 1}, "bad.yaml")
    assert main(["check-config", str(bad)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"{bad}: plant: key 'enabled': must be true or false, was 'yes'",
        f"{bad}: plant: key 'max_samples': must be in 64..65536, was 10",
        f"{bad}: plant: unknown key 'colour'"]
    assert main(["check-config", str(_plant_cfg(tmp_path, {"enabled": False}))]) == 0
    with pytest.raises(ConfigError, match="plant"):
        parse_config({**yaml.safe_load(bad.read_text()), "plant": []})


def test_reload_turns_the_plant_step_off_and_on(tmp_path: Path) -> None:
    on = _plant_cfg(tmp_path, {"enabled": True, "max_samples": 512}, "on.yaml")
    off = _plant_cfg(tmp_path, {"enabled": False}, "off.yaml")

    async def go() -> list[PlantSettings]:
        seen = []
        async with Gateway(load_config(on), serve_http=False,
                           executor=lambda: ThreadPoolExecutor(1)) as gw:
            seen.append(gw.scheduler.plant)
            assert await gw.reload(off)
            seen.append(gw.scheduler.plant)
            assert await gw.reload(on)
            seen.append(gw.scheduler.plant)
        return seen

    assert asyncio.run(asyncio.wait_for(go(), 30)) == [
        PlantSettings(True, 512), PlantSettings(False), PlantSettings(True, 512)]
