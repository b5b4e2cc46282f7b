"""core.jobs: what an analysis worker runs, with literal windows."""

from __future__ import annotations

import numpy as np
from detector_fixtures import cached_sim

from gateway.core.jobs import LoopJob, analyze_batch, bad_values_reason, batches
from gateway.core.points import Quality
from gateway.core.windows import LoopGroup, WindowBank
from stiction import Verdict, analyze

G, B, N = Quality.GOOD, Quality.BAD, Quality.NO_COMM
FAKE = "gateway_fake_analyze:analyze"


def job(op: np.ndarray, quality: np.ndarray, index: int = 0, size: int | None = None
        ) -> LoopJob:
    n = len(op)
    return LoopJob(index, op.astype(np.float32), np.full(n, 20.0, np.float32),
                   quality.astype(np.uint8), size=size or 2 * n, ts=1.0, kp=None, delay=0.0,
                   process="self-regulating", op_range=(0.0, 100.0))


def test_bad_values_reason() -> None:
    assert bad_values_reason(np.full(50, G, np.uint8), 50) is None
    tail = np.array([G] * 46 + [B] * 4, np.uint8)
    assert bad_values_reason(tail, 46).startswith("the latest 4 samples are bad values")
    few = np.array([B] * 10 + [G] * 20, np.uint8)
    assert bad_values_reason(few, 20).startswith("only 20 usable samples")
    assert bad_values_reason(np.array([B] * 10 + [G] * 40, np.uint8), 40) is None
    assert bad_values_reason(np.array([N] * 10 + [G] * 5, np.uint8), 5) is None  # stale


def test_analyze_batch_fill_bad_data_and_the_analysis() -> None:
    t = np.arange(100)
    swing = 50 + 10 * np.sign(np.sin(t / 5))
    out = analyze_batch(FAKE, [
        job(swing, np.full(100, G)),
        job(swing, np.array([G] * 90 + [B] * 10), index=1),
        job(swing, np.full(100, N), index=2),
        job(swing, np.full(100, G), index=3, size=100),
    ])
    (i0, a0, fill0, n0, _, swing0), (i1, a1, *_), (i2, a2, fill2, n2, _, swing2), \
        (_, a3, *_) = out
    # the PV's swing over the samples used (the list worst first): half its 2-98 % range
    assert swing0 == 0.0 and swing2 is None  # (PV stands at 20; no samples)
    # half the window, one cycle of the 100 s the fake analysis reports: not yet judged
    assert (i0, a0.verdict, fill0, n0) == (0, Verdict.WARMING_UP, 0.5, 100)
    assert "its cycle of 100 s shows in 2.6 cycles" in a0.reason
    assert a3.verdict == Verdict.STICTION  # the full window: as analysed
    assert i1 == 1 and a1.verdict == Verdict.BAD_DATA and "bad values" in a1.reason
    assert (i2, a2.verdict, fill2, n2) == (2, Verdict.BAD_DATA, 0.0, 0)
    assert a2.reason == "no usable samples in the window yet"


def test_a_failing_analysis_is_bad_data_not_a_crash() -> None:
    (_, a, _, _, _, _), = analyze_batch("test_jobs:_raises",
                                   [job(np.ones(40), np.full(40, G), size=40)])
    assert a.verdict == Verdict.BAD_DATA
    assert a.reason == "analysis failed: ZeroDivisionError: no"


def _raises(*_: object, **__: object) -> None:
    raise ZeroDivisionError("no")


def test_batches_copy_windows_batch_by_batch() -> None:
    bank = WindowBank([f"L{i}" for i in range(5)], 16)
    for k in range(3):
        bank.append(float(k), np.arange(5.0) + k, np.zeros(5), np.zeros(5, np.uint8))
    rows = np.arange(10, 15, dtype=np.intp)
    cfg = __import__("types").SimpleNamespace(kp=1.5, delay_s=2.0, process="integrating",
                                              op_range=(0.0, 100.0))
    group = LoopGroup("d", bank, (cfg,) * 5, rows, rows, rows, 0.5)  # type: ignore[arg-type]
    empty = LoopGroup("e", WindowBank(["X"], 16), (cfg,), rows[:1], rows[:1], rows[:1], 1.0)  # type: ignore[arg-type]
    got = list(batches([empty, group], 2))
    assert [[j.index for j in b] for b in got] == [[10, 11], [12, 13], [14]]
    j = got[1][1]
    assert j.op.tolist() == [3.0, 4.0, 5.0] and j.size == 16 and j.ts == 0.5
    assert (j.kp, j.delay, j.process) == (1.5, 2.0, "integrating")


def _sim(name: str, seconds: int) -> tuple[np.ndarray, np.ndarray]:
    r = cached_sim(name, 0.02, 3)
    return r.op[:seconds].astype(np.float32), r.pv[:seconds].astype(np.float32)


def _real_job(op: np.ndarray, pv: np.ndarray, size: int, process: str) -> LoopJob:
    return LoopJob(0, op, pv, np.full(len(op), G, np.uint8), size=size, ts=1.0, kp=None,
                   delay=0.0, process=process, op_range=(0.0, 100.0))


def test_a_window_still_filling_is_warming_up_never_not_oscillating() -> None:
    """Issue 23 item 4: a loop under a load cycling every 10 min, 10 minutes into a 2-hour
    window, shows no oscillation yet (its cycle needs more of the window); the verdict says
    the window is warming up, how full it is and what it waits for, not `not_oscillating`.
    (Issue 31: the wait is the loop's own time scale, estimated from the window.)"""
    op, pv = _sim("disturbance", 600)
    assert analyze(op, pv, ts=1.0).verdict == Verdict.NOT_OSCILLATING
    (_, a, _, n, _, _), = analyze_batch("stiction:analyze",
                                     [_real_job(op, pv, 7200, "self-regulating")])
    assert (a.verdict, n) == (Verdict.WARMING_UP, 600)
    assert a.reason == ("warming up: window fill 8%, 10 min of 2 h analysed; OP and PV move on "
                        "a 7 min time scale (a cycle that slow shows in 2.6 of it): judged in "
                        "9 min at the earliest, calm only when full in 1 h 50 min")
    assert len(a.reason) <= 200  # the journal's verdict-change line keeps it whole
    # a sticky valve's full window: stiction, as before
    op, pv = _sim("table5-case2", 4000)
    (_, a, _, _, _, _), = analyze_batch("stiction:analyze",
                                     [_real_job(op, pv, 4000, "integrating")])
    assert a.verdict == Verdict.STICTION


def test_a_short_window_after_a_restart_is_warming_up_not_a_verdict() -> None:
    """Issue 31 item 2: after a start or an outage the window restarts and the first rounds
    on 33-45 samples published what the analysis said: a healthy loop read `stiction` at
    0.95, a sticky one `bad_data` ("window too short: 9 samples"). Now each is warming up,
    saying what it waits for; the windows here are the demo's healthy loop (30 min). On main
    the 9 samples were bad_data and the 33 from 4125 s `stiction` at 0.89."""
    op, pv = _sim("healthy", 4200)
    for start, length in ((1000, 9), (1200, 33), (4125, 33), (1500, 45), (2000, 60)):
        seg = slice(start, start + length)
        (_, a, _, n, _, _), = analyze_batch("stiction:analyze", [
            _real_job(op[seg], pv[seg], 1800, "self-regulating")])
        assert (a.verdict, n) == (Verdict.WARMING_UP, length), a.reason
        assert ("a verdict needs 64 samples: judged in " in a.reason) == (length < 64)
        assert len(a.reason) <= 200


def test_a_full_window_without_oscillation_is_not_oscillating() -> None:
    op, pv = _sim("healthy", 3600)
    (_, a, _, _, _, _), = analyze_batch("stiction:analyze",
                                     [_real_job(op, pv, 3600, "self-regulating")])
    assert a.verdict == Verdict.NOT_OSCILLATING
