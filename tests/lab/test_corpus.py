"""The development corpus's machinery without tep-studio and without the built corpus: the
valve rebuilt from OP, the labels, the windowing of a synthetic run, the plan, the folds,
the realistic part's determinism at a tiny size and the shared records' loaders."""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest
from deploy_support import require

from lab._types import SOURCES, Window, counts, folds
from lab.labels import rules
from lab.labels.tep import tep_records
from lab.sources import realistic, records, tep, tep_plan
from lab.windows import tep as cut


# ----------------------------------------------------------------------------- the valve
def test_valve_command_follows_op_only_past_the_band() -> None:
    op = np.linspace(0.0, 10.0, 1001)  # a slow ramp
    cmd = tep.valve_command(op, 1.0)
    assert np.all(np.abs(cmd - op) <= 1.0 + 1e-12)
    jumps = np.diff(cmd)[np.diff(cmd) != 0]
    assert jumps.size == 9 and np.all(jumps > 1.0)  # a stick-slip staircase
    assert np.array_equal(tep.valve_command(op[:50], 1.0), np.zeros(50))  # inside the band


def test_valve_command_starts_where_told() -> None:
    assert tep.valve_command(np.array([5.0, 5.5, 7.5]), 1.0, start=6.0).tolist() == \
        [6.0, 6.0, 7.5]


def test_lagged_is_a_first_order_step_response() -> None:
    y = tep.lagged(np.ones(10), 1.8, 5.0, 0.0)
    t = 1.8 * np.arange(1, 11)
    assert np.allclose(y, 1.0 - np.exp(-t / 5.0))


def _stick_slip(n: int, band: float, *, period: float = 300.0, ts: float = 1.8,
                noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """OP of a stick-slip limit cycle: a triangle 1.2 bands high (ramps while stuck, two
    slips a cycle)."""
    t = ts * np.arange(n)
    tri = 2.0 * np.abs((t / period) % 1.0 - 0.5) - 0.5
    return 40.0 + 1.2 * band * tri + noise * np.random.default_rng(seed).standard_normal(n)


def test_valve_stats_tell_stick_slip_from_dither_and_from_stuck() -> None:
    band = 2.0
    cyc = rules.valve_stats(tep.valve_command(_stick_slip(4000, band), band), 1.8)
    assert cyc.cause_class == "stiction"
    assert cyc.held > 0.9 and cyc.period_s == pytest.approx(300.0, rel=0.1)
    noisy = 40.0 + 3.0 * np.random.default_rng(1).standard_normal(4000)
    dith = rules.valve_stats(tep.valve_command(noisy, band), 1.8)
    assert dith.cause_class == "stiction-masked" and dith.median_hold < rules.MIN_HOLD
    still = 40.0 + 0.1 * np.random.default_rng(2).standard_normal(4000)
    stuck = rules.valve_stats(tep.valve_command(still, band), 1.8)
    assert stuck.cause_class == "stiction-stuck" and stuck.slips == 0
    assert math.isnan(stuck.period_s)


# ------------------------------------------------------------------------- other loops
def _summary(x: np.ndarray, y: np.ndarray) -> cut.LoopSummary:
    f, p = cut._spectrum(x)
    _, q = cut._spectrum(y)
    return cut.LoopSummary(float(x.std()), float(y.std()), f, p, q)


def test_other_loops_are_labelled_against_the_normal_runs() -> None:
    rng = np.random.default_rng(3)
    n = 20000
    normals = [_summary(rng.standard_normal(n), rng.standard_normal(n)) for _ in range(3)]
    ref = rules.Reference.of(normals)
    assert ref.op_sd == max(s.op_sd for s in normals)
    same = _summary(rng.standard_normal(n), rng.standard_normal(n))
    t = 1.8 * np.arange(n)
    cycling = _summary(rng.standard_normal(n) + 2.0 * np.sin(2 * np.pi * t / 300.0),
                       rng.standard_normal(n))
    louder = _summary(3.0 * rng.standard_normal(n), rng.standard_normal(n))
    f0 = [1.0 / 300.0]
    kw = {"sticky": True, "cycles_hz": f0}
    assert rules.other_label(same, ref, disturbed=False, **kw).cause_class == "normal"
    got = rules.other_label(cycling, ref, disturbed=True, **kw)
    assert got.cause_class == "propagated" and got.cycle_ratio > rules.CYCLE_RATIO
    assert rules.other_label(louder, ref, disturbed=True, **kw).cause_class == "disturbance"
    assert rules.other_label(louder, ref, disturbed=False, **kw).cause_class == "propagated"
    assert rules.other_label(louder, ref, sticky=False, cycles_hz=[], disturbed=False
                           ).cause_class == "normal"
    with pytest.raises(ValueError, match="at least one normal run"):
        rules.Reference.of([])


# ------------------------------------------------------------------------------ the plan
def test_plan_every_disturbance_at_three_magnitudes_and_normal_runs_first() -> None:
    runs = tep_plan.plan()
    assert len({r.id for r in runs}) == len(runs) == len({(r.mode, r.seed) for r in runs})
    for idv in tep_plan.ALONE:
        mags = {r.idvs[0][1] for r in runs if len(r.idvs) == 1 and r.idvs[0][0] == idv
                and not r.sticky}
        assert mags == {0.25, 0.5, 1.0}, idv
    for mode in tep_plan.MODES:
        mine = [r for r in runs if r.mode == mode]
        assert [r.cause for r in mine[:3]] == ["normal"] * 3
        assert {b for r in mine for i, b in r.sticky if i == 14} == set(tep_plan.BANDS[14])
    run = tep_plan.TepRun("mode2", 7, ((11, 1.0),), ((14, 2.0),))
    assert (run.cause, run.id, run.bands) == ("idv14+idv11", "mode2-idv14@2%+idv11@1-s7", {9: 2.0})
    assert tep_plan.TepRun("mode1", 1, (), ((19, 4.0),)).bands == \
        {4: 4.0, 6: 4.0, 7: 4.0, 8: 4.0}


def test_bands_map_to_idv_magnitude_then_to_the_models_vst() -> None:
    vec = tep.idv_vector([(11, 0.5)], {9: 1.0})
    assert vec[10] == 0.5 and vec[13] == 0.5  # 1 % = IDV 14 at 0.5 of the model's 2 %
    assert tep.model_bands({9: 1.0}) == {}  # no rewrite needed up to 2 %
    assert tep.idv_vector([], {10: 8.0})[14] == 1.0
    assert tep.model_bands({10: 8.0}) == {10: 8.0}
    assert tep.model_seed(0) % 2 == 1 and tep.model_seed(3) != tep.model_seed(4)


# --------------------------------------------------------------- a synthetic run's windows
def _arrays(run: tep_plan.TepRun, seed: int) -> types.SimpleNamespace:
    """What lab.sources.tep.run returns, made up: noise on every loop, and a stick-slip cycle on
    the sticky valve's loop with its position as the model would move it."""
    rng = np.random.default_rng(seed)
    n = round((cut.RECORD_H[1] - cut.RECORD_H[0]) * 3600 / cut.TS)
    m = len(tep.LOOPS)
    op = 40.0 + 0.1 * rng.standard_normal((n, m))
    pv = 1.0 + 0.01 * rng.standard_normal((n, m))
    pos = op.copy()
    for j, lp in enumerate(tep.LOOPS):
        if lp.xmv in run.bands:
            band = run.bands[lp.xmv]
            op[:, j] = _stick_slip(n, band, seed=seed)
            cmd = tep.valve_command(op[:, j], band)
            pos[:, j] = tep.lagged(cmd, cut.TS, cut.VALVE_TAU, cmd[0])
            pv[:, 0] += 0.05 * (pos[:, j] - pos[:, j].mean())  # the cycle reaches XMV1
    t = cut.RECORD_H[0] + cut.TS / 3600 * np.arange(1, n + 1)
    return types.SimpleNamespace(t=t, op=op, pv=pv, sp=pv.copy(), pos=pos,
                                 xmeas=rng.standard_normal((n, 41)), tripped="")


def test_a_synthetic_run_is_cut_into_labelled_windows_and_a_plant_run() -> None:
    normal = tep_plan.TepRun("mode1", 1)
    sticky = tep_plan.TepRun("mode1", 2, (), ((14, 2.0),))
    reduced = [cut.reduce(r, _arrays(r, k)) for k, r in enumerate((normal, sticky))]
    windows, plant_runs = tep_records(reduced)
    assert len(windows) == 2 * len(tep.LOOPS) * 4  # 2 gateway, historian, study
    views = {(w.view, w.ts, w.op.size) for w in windows}
    assert views == {("gateway", 1.8, 4000), ("historian", 36.0, 2400), ("study", 180.0, 480)}
    mine = [w for w in windows if w.run == sticky.id]
    valve = [w for w in mine if w.loop == "XMV10"]
    assert {w.cause_class for w in valve} == {"stiction"}
    assert all(w.sticky and w.stiction_size == 2.0 and w.cause == "idv14" for w in valve)
    assert all(w.meta["model_error"] < 1e-3 for w in valve)
    gw = next(w for w in valve if w.view == "gateway")
    assert gw.meta["valve_position"].shape == gw.op.shape
    labels = {w.loop: w.cause_class for w in mine if w.view == "historian"}
    assert labels["XMV1"] == "propagated"
    assert {labels[n] for n in labels if n not in ("XMV1", "XMV10")} == {"normal"}
    assert {w.cause_class for w in windows if w.run == normal.id} == {"normal"}
    assert {w.source for w in windows} == {"tep-mode1"}
    pr = next(p for p in plant_runs if p.id == sticky.id)
    assert pr.sticky_loop == "XMV10" and pr.external is False and pr.ts == 36.0
    assert set(pr.loops) == {lp.name for lp in tep.LOOPS} and len(pr.indicators) == 32
    assert pr.labels == labels


# ----------------------------------------------------------------------------- the folds
def _w(source: str, run: str, cls: str = "normal") -> Window:
    return Window(source, run, "loop", cls, cls, cls == "stiction", np.zeros(3), np.zeros(3),
                  1.0, "self-regulating", "", 0.0)


def test_folds_keep_each_run_in_one_source() -> None:
    ws = [_w("tep-mode1", "a"), _w("tep-mode1", "a", "stiction"), _w("plant", "b"),
          _w("realistic", "c")]
    assert folds(ws) == {"tep-mode1": [0, 1], "plant": [2], "realistic": [3]}
    assert counts(ws)[("tep-mode1", "stiction")] == 1
    with pytest.raises(ValueError, match="run 'a' is in sources"):
        folds([*ws, _w("tep-mode2", "a")])
    assert set(SOURCES) >= {w.source for w in ws}


# ---------------------------------------------------------------- realistic, shared data
def test_realistic_part_is_deterministic(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(realistic, "REALISTIC_SEEDS", (11,))
    monkeypatch.setattr(realistic, "REALISTIC_CAUSES", ("noise", "tuning"))
    monkeypatch.setattr(realistic, "REALISTIC_PER_CAUSE", 1)
    built = []
    for sub in ("a", "b"):
        assert realistic.build_realistic(tmp_path / sub, lambda s: None) == 2
        assert realistic.build_realistic(tmp_path / sub, lambda s: None) == 0  # cached
        built.append(realistic.realistic_windows(tmp_path / sub))
    a, b = built
    assert [w.key for w in a] == [w.key for w in b] and len(a) == 2
    assert all(np.array_equal(x.op, y.op) and np.array_equal(x.pv, y.pv)
               for x, y in zip(a, b, strict=True))
    assert {w.cause_class for w in a} == {"normal", "tuning"}
    assert not any(w.sticky for w in a) and {w.source for w in a} == {"realistic"}


def test_shared_record_names_give_run_loop_and_idv() -> None:
    assert records._shared_run("braatz/d14_te_reactor_cw") == \
        ("braatz/d14_te", "reactor_cw", 14)
    assert records._shared_run("braatz/d00_condenser_cw") == \
        ("braatz/d00", "condenser_cw", None)
    assert records._shared_run("ricker/idv07_separator_temp") == \
        ("ricker/idv07", "separator_temp", 7)


def _needs_shared() -> None:
    """The records beside the repository: a missing folder skips locally and fails under
    CI=true, as a missing tool does (issue 31: these tests skipped under CI)."""
    require(records.SHARED.exists(), f"{records.SHARED} not found (../shared/data)")


def test_shared_records_load_with_their_labels() -> None:
    _needs_shared()
    plant = records.plant_windows()
    assert len(plant) == 80 and sum(w.sticky for w in plant) == 35
    assert len({w.run for w in plant}) == 34  # a run per tag
    tep = records.shared_tep_windows()
    assert len(tep) == 58
    assert {w.cause for w in tep if w.sticky} == {"idv14", "idv15"}
    runs = records.shared_tep_plant_runs(tep)
    d14 = next(r for r in runs if r.id == "tep-shared-braatz/d14")
    assert d14.sticky_loop == "reactor_cw" and d14.labels["condenser_cw"] == "propagated"
    cases = records.case_windows()
    assert [(w.cause_class, w.sticky) for w in cases] == [("tuning", False)]
    folds(plant + tep + cases)  # no run in two folds


def test_load_windows_without_a_built_corpus(tmp_path) -> None:
    _needs_shared()
    from lab.labels import corpus  # noqa: PLC0415

    ws = corpus.load_windows(cache=tmp_path)  # nothing simulated: the shared records only
    assert {w.source for w in ws} == {"plant", "tep-shared", "cases"}
    assert corpus.load_windows(["cases"], cache=tmp_path)[0].source == "cases"
    with pytest.raises(ValueError, match="unknown sources"):
        corpus.load_windows(["tep"], cache=tmp_path)
    assert all(dataclasses.is_dataclass(r) for r in corpus.load_plant_runs(cache=tmp_path))
