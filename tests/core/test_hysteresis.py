"""Verdict hysteresis (issue 32 item 3) and judgements held through warming up (issue 31
item 2), on literal assessments: core/hysteresis.py, the config keys, the scheduler's wiring
and the metric."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from memory_harness import mconfig, mloop
from prometheus_client import CollectorRegistry

from gateway.config import HysteresisSettings, parse_config
from gateway.core.hysteresis import VerdictFilter
from gateway.core.points import Quality
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup, WindowBank, load_columns
from gateway.errors import ConfigError
from gateway.inputs.memory import memory_device
from gateway.outputs.prometheus.devices import GatewayMetrics
from gateway.runtime.scheduler import AnalysisScheduler
from stiction import Assessment, Verdict

S, U, N = Verdict.STICTION, Verdict.UNDETERMINED, Verdict.NO_STICTION


def a(verdict: Verdict, confidence: float | None = None, reason: str = "r",
      fd: float | None = None) -> Assessment:
    return Assessment(verdict, reason, confidence=confidence, fd=fd)


def test_a_verdict_near_its_threshold_does_not_chatter() -> None:
    """The demo's sticky level loop: stiction -> undetermined -> stiction -> undetermined ->
    stiction in 90 s (issue 32). Published: stiction, every round. (Every round counts
    here: ``band`` 0; a confidence at its threshold is the next test's.)"""
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5, band=0.0))
    seq = [a(S, 0.88, "first", fd=0.27), a(U, 0.85), a(S, 0.89, "third", fd=0.26), a(U, 0.84),
           a(U, 0.86), a(S, 0.90, "sixth", fd=0.28)]
    out = [f.publish("LIC201", x, float(t)) for t, x in enumerate(seq)]
    assert [o.verdict for o in out] == [S] * 6
    assert out[1].fd == 0.27 and out[1].reason.startswith(
        "held: this round says undetermined (confidence 0.85), published when it holds 5 "
        "rounds (1 so far) or its confidence moves 0.5 from 0.88. first")
    assert out[4].reason.startswith("held: this round says undetermined (confidence 0.86), "
                                    "published when it holds 5 rounds (2 so far)")
    assert out[5].reason == "sixth"  # the same verdict again: its own, newest numbers
    assert f.counts == {"published": 0, "held_back": 3}


def test_a_change_that_holds_is_published_after_its_rounds() -> None:
    f = VerdictFilter(HysteresisSettings(rounds=3, margin=0.5))
    f.publish("L", a(S, 0.9, fd=0.2), 0.0)
    out = [f.publish("L", x, float(t)) for t, x in enumerate([a(U, 0.8), a(N, 0.6),
                                                              a(U, 0.75, "latest")], 1)]
    assert [o.verdict for o in out] == [S, S, U]
    assert out[-1].reason == "latest" and out[-1].fd is None
    assert f.counts == {"published": 1, "held_back": 2}


def test_evidence_that_moved_by_the_margin_is_published_at_once() -> None:
    """A valve repaired: stiction 0.95 -> no_stiction 0.2 in the next round."""
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    f.publish("L", a(S, 0.95), 0.0)
    assert f.publish("L", a(N, 0.2), 1.0).verdict == N
    assert f.publish("L", a(U, 0.6), 2.0).verdict == N  # moved 0.4 < 0.5: held
    # between judgements other than stiction only the rounds count: the demo plant's
    # FIC102 read no_stiction 0.05, undetermined 0.63, no_stiction 0.06
    g = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    g.publish("FIC102", a(N, 0.05), 0.0)
    assert g.publish("FIC102", a(U, 0.63), 1.0).verdict == N
    # a verdict without a confidence waits its rounds
    assert f.publish("L", a(Verdict.VALVE_NOT_RESPONDING), 3.0).verdict == N


def test_rounds_one_publishes_every_verdict() -> None:
    f = VerdictFilter(HysteresisSettings(rounds=1, margin=1.0))
    got = [f.publish("L", a(v, c), 0.0).verdict for v, c in ((S, 0.9), (U, 0.85), (S, 0.88))]
    assert got == [S, U, S]


def test_a_judgement_is_held_while_its_window_warms_up_again() -> None:
    """Issue 31: after an outage the window restarts; a sticky loop went stiction ->
    bad_data -> warming_up. Now it keeps saying stiction, held and since when, until it is
    judged again."""
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    f.publish("L", a(S, 0.93, "sticky", fd=0.27), 1_772_344_800.0)  # 2026-03-01 06:00 UTC
    warm = Assessment(Verdict.WARMING_UP, "warming up: window fill 3%, ...")
    out = [f.publish("L", warm, 1_772_345_100.0 + k * 300) for k in range(3)]
    assert [o.verdict for o in out] == [S, S, S]
    assert all(o.fd == 0.27 for o in out)
    assert out[2].reason == ("held since 2026-03-01 06:05:00 UTC, last judged 2026-03-01 "
                             "06:00:00 UTC: warming up: window fill 3%, .... sticky")
    assert f.publish("L", a(S, 0.91, "again"), 1_772_346_000.0).reason == "again"
    assert f.counts["held_back"] == 3


def test_what_passes_at_once() -> None:
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5))
    warm = Assessment(Verdict.WARMING_UP, "warming up")
    assert f.publish("L", warm, 0.0).verdict == Verdict.WARMING_UP  # nothing judged yet
    assert f.publish("L", a(S, 0.9), 1.0).verdict == S  # the first judgement
    bad = Assessment(Verdict.BAD_DATA, "the latest 5 samples are bad values")
    assert f.publish("L", bad, 2.0).verdict == Verdict.BAD_DATA  # a data fault: at once
    assert f.publish("L", a(N, 0.3), 3.0).verdict == N  # and the judgement after it
    assert f.publish("L", warm, 4.0).verdict == N  # held
    assert f.counts == {"published": 0, "held_back": 1}


def test_a_restored_result_is_held_like_a_published_one() -> None:
    """After a restart without windows (or a reload) the loop's restored result is what
    it shows: a warming-up window holds it."""
    f = VerdictFilter()
    restored = a(S, 0.9, "from the state file", fd=0.3)
    out = f.publish("L", Assessment(Verdict.WARMING_UP, "warming up"), 5.0, shown=restored)
    assert out.verdict == S and out.reason.endswith("from the state file")
    # a held result restored (the state file was written while it was held): the judgement
    held = f.publish("L", Assessment(Verdict.WARMING_UP, "warming up"), 6.0)
    g = VerdictFilter()
    again = g.publish("L", Assessment(Verdict.WARMING_UP, "warming up"), 7.0, shown=held)
    assert again.reason.count("held since") == 1 and again.reason.endswith("from the state file")
    propagated = Assessment(Verdict.PROPAGATED, "plant")  # not a per-loop judgement
    assert f.publish("M", Assessment(Verdict.WARMING_UP, "w"), 5.0,
                     shown=propagated).verdict == Verdict.WARMING_UP
    f.keep(["M"])
    assert f.publish("L", a(N, 0.1), 6.0).verdict == N  # forgotten: a first verdict


def test_a_confidence_at_its_threshold_neither_counts_nor_resets() -> None:
    """The demo's U2.TIC201 on an AMD EPYC machine (issue 35): published undetermined from
    its filling window, then no_stiction four rounds, then undetermined 0.507 against the
    threshold 0.5 for one round, which restarted the count, then no_stiction again: the
    change came only after the window was full. The round at its threshold is not counted,
    so the change comes in the fifth round that says it."""
    f = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5, band=0.02))
    f.publish("TIC201", a(U, 0.70), 0.0)
    seq = [a(N, 0.25), a(N, 0.46), a(N, 0.36), a(N, 0.32), a(U, 0.507), a(N, 0.21)]
    out = [f.publish("TIC201", x, float(t)) for t, x in enumerate(seq, 1)]
    assert [o.verdict for o in out] == [U, U, U, U, U, N]
    assert out[4].reason == "r"  # the published verdict's own round: its newest numbers
    # differing at the threshold: held and said, not counted
    g = VerdictFilter(HysteresisSettings(rounds=2, margin=0.5, band=0.02))
    g.publish("L", a(N, 0.3), 0.0)
    held = g.publish("L", a(U, 0.51), 1.0)
    assert held.verdict == N and "within 0.02 of the decision's threshold 0.5: not " \
        "counted, published when it holds 2 rounds (0 so far)" in held.reason
    assert g.publish("L", a(U, 0.6), 2.0).verdict == N  # the first round that counts
    assert g.publish("L", a(U, 0.6), 3.0).verdict == U
    # band 0: every round counts, as before
    h = VerdictFilter(HysteresisSettings(rounds=5, margin=0.5, band=0.0))
    h.publish("TIC201", a(U, 0.70), 0.0)
    assert [h.publish("TIC201", x, float(t)).verdict for t, x in enumerate(seq, 1)] == [U] * 6


def _raw() -> dict[str, object]:
    return mconfig([memory_device("plc", [[50.0, 20.0]])],
                   [mloop("L", "plc", 0, 0, window_s=400.0)])


def test_config_keys() -> None:
    base = _raw()
    assert parse_config(base).hysteresis == HysteresisSettings(5, 0.5, 0.02)
    c = parse_config({**base, "verdict_hysteresis": {"rounds": 2, "margin": 0.3, "band": 0}})
    assert c.hysteresis == HysteresisSettings(2, 0.3, 0.0)
    with pytest.raises(ConfigError) as info:
        parse_config({**base, "verdict_hysteresis": {"rounds": 0, "margin": 1.5, "x": 1,
                                                     "band": 0.6}})
    text = str(info.value)
    assert "verdict_hysteresis: key 'rounds': must be in 1..1000, was 0" in text
    assert "verdict_hysteresis: key 'margin': must be <= 1, was 1.5" in text
    assert "verdict_hysteresis: key 'band': must be <= 0.5, was 0.6" in text
    assert "verdict_hysteresis: unknown key 'x'" in text


def test_the_scheduler_publishes_through_the_filter_and_counts() -> None:
    """Two rounds on one window: the fake analysis says stiction, then (the window's OP
    swing gone) not_oscillating; the second is held back, counted in the metric."""
    bank = WindowBank(["L"], 400)
    swing = (50 + 20 * np.sign(np.sin(np.arange(400) / 8))).astype(np.float32)
    q = np.full(400, Quality.GOOD, np.uint8)
    load_columns(bank, np.arange(400.0), {0: (swing, np.full(400, 20.0, np.float32), q)})
    cfg = parse_config(_raw()).loops[0]
    cols = np.zeros(1, np.intp)
    group = LoopGroup("plc", bank, (cfg,), cols, cols, cols, 1.0)
    store = ResultStore(["L"])
    metrics = GatewayMetrics(CollectorRegistry())

    async def go() -> list[str]:
        sched = AnalysisScheduler([group], store, interval_wall_s=1e9,
                                  analyze="gateway_fake_analyze:analyze",
                                  executor=lambda: ThreadPoolExecutor(1),
                                  hysteresis=HysteresisSettings(5, 0.5),
                                  on_verdict=metrics.count_verdict)
        await sched.start()
        try:
            await sched.run_round(now=lambda: 100.0)
            first = store.verdict_name(0)
            load_columns(bank, np.arange(400.0), {0: (np.full(400, 50.0, np.float32),
                                                      np.full(400, 20.0, np.float32), q)})
            await sched.run_round(now=lambda: 200.0)
            return [first, store.verdict_name(0)]
        finally:
            await sched.stop()

    assert asyncio.run(go()) == ["stiction", "stiction"]
    res = store.results[0]
    assert res is not None and res.t == 200.0 and res.seq == 2
    assert res.assessment.reason.startswith("held: this round says not_oscillating")
    reg = metrics.registry
    assert reg.get_sample_value("stiction_verdict_changes_total",
                                {"outcome": "held_back"}) == 1.0
    assert reg.get_sample_value("stiction_verdict_changes_total",
                                {"outcome": "published"}) == 0.0
