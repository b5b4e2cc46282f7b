"""core.windows: ring buffers, the analysis segment, loading and recording samples,
window signatures."""

from __future__ import annotations

import dataclasses

import numpy as np

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.core.store import ResultStore
from gateway.core.windows import (
    LoopGroup,
    WindowBank,
    analysis_segment,
    load_columns,
    loop_signature,
    record,
    result_signature,
)
from gateway.inputs.memory import memory_device

G, N, B, M = Quality.GOOD, Quality.NO_COMM, Quality.BAD, Quality.MISSING


def test_ring_buffer_wraps_in_time_order() -> None:
    bank = WindowBank(["A", "B"], 4)
    assert bank.op.dtype == np.float32
    assert bank.quality.dtype == np.uint8
    for k in range(6):
        bank.append(float(k), np.array([k, 10 + k]), np.array([-k, -10 - k]),
                    np.array([G, N if k == 5 else G], dtype=np.uint8))
    t, op, pv, q = bank.series([0, 1])
    assert t.tolist() == [2.0, 3.0, 4.0, 5.0]
    assert op.tolist() == [[2, 3, 4, 5], [12, 13, 14, 15]]
    assert pv[1].tolist() == [-12, -13, -14, -15]
    assert q[1].tolist() == [G, G, G, N]
    assert bank.count == 4
    op_l, _pv_l, q_l = bank.latest()
    assert op_l.tolist() == [5, 15]
    assert q_l.tolist() == [G, N]
    t, op, _, _ = WindowBank(["A"], 8).series([0])
    assert len(t) == 0
    # bytes per stored sample per loop: 4 (op) + 4 (pv) + 1 (quality), plus 8 per row
    big = WindowBank([f"L{i}" for i in range(1000)], 3600)
    assert big.nbytes == 3600 * 1000 * 9 + 3600 * 8


def test_analysis_segment_fills_short_gaps_and_cuts_at_long_ones() -> None:
    op = np.arange(12, dtype=np.float32)
    pv = op * 2
    q = np.array([N, G, G, N, N, N, N, G, G, N, G, G], dtype=np.uint8)
    o, p = analysis_segment(op, pv, q, max_fill=3)
    assert o.tolist() == [7, 8, 9, 10, 11]  # after the 4-sample gap; 1-sample gap filled
    assert p.tolist() == [14, 16, 18, 20, 22]
    q2 = np.array([G] * 8 + [N] * 4, dtype=np.uint8)  # trailing outage: keep what came before
    assert analysis_segment(op, pv, q2)[0].tolist() == list(range(8))
    assert len(analysis_segment(op, pv, np.full(12, N, dtype=np.uint8))[0]) == 0


def test_load_columns_aligns_series_at_their_newest_sample() -> None:
    bank = WindowBank(["A", "B", "C"], 4)
    t = np.arange(6, dtype=np.float64)
    load_columns(bank, t, {
        0: (np.arange(6.0), np.arange(6.0) + 10, np.zeros(6, np.uint8)),
        1: (np.array([7.0, 8.0]), np.array([1.0, 2.0]), np.array([G, B], np.uint8)),
    })
    t2, op, pv, q = bank.series([0, 1, 2])
    assert t2.tolist() == [2.0, 3.0, 4.0, 5.0]  # the newest 4 rows
    assert op[0].tolist() == [2, 3, 4, 5] and pv[0].tolist() == [12, 13, 14, 15]
    assert op[1][2:].tolist() == [7, 8] and q[1].tolist() == [M, M, G, B]
    assert (q[2] == M).all()  # a column not given stays empty
    bank.append(6.0, np.zeros(3), np.zeros(3), np.zeros(3, np.uint8))
    assert bank.series([0])[0].tolist() == [3.0, 4.0, 5.0, 6.0]  # appends go on after


def test_record_appends_one_row_per_group_and_says_what_was_fresh() -> None:
    store = ResultStore(["A", "B", "C"])

    def group(loops: list[str], cols: list[int], rows: list[int]) -> LoopGroup:
        c = np.array(cols, dtype=np.intp)
        return LoopGroup("d", WindowBank(loops, 16), (), 2 * c, 2 * c + 1,
                         np.array(rows, dtype=np.intp), 1.0)

    groups = [group(["A", "C"], [0, 2], [0, 2]), group(["B"], [1], [1])]
    values = np.array([50.0, 20.0, 51.0, np.nan, 52.0, 22.0])
    quality = np.array([G, G, G, N, G, B], np.uint8)
    fresh = record(groups, 7.0, values, quality, store)
    assert fresh.tolist() == [True, True, False]  # A, C (BAD is fresh), B (NO_COMM is not)
    _t, op, _pv, q = groups[0].bank.series([0, 1])
    assert op[:, 0].tolist() == [50.0, 52.0] and q[:, 0].tolist() == [G, B]
    assert store.latest_op.tolist() == [50.0, 51.0, 52.0]
    assert np.isnan(store.latest_pv[1]) and store.latest_pv[0] == 20.0


def test_window_signature_follows_what_the_samples_mean() -> None:
    raw = {"devices": [memory_device("m", [[1.0, 2.0]])],
           "loops": [{"name": "A", "device": "m", "op": {"column": 0}, "pv": {"column": 1},
                      "window_s": 60, "result_address": 0}]}
    cfg = parse_config(raw)
    lp = cfg.loops[0]
    moved = dataclasses.replace(lp, result_address=20)
    assert loop_signature(cfg, moved) == loop_signature(cfg, lp)
    assert result_signature(cfg, moved) == result_signature(cfg, lp)  # address: no matter
    tuned = dataclasses.replace(lp, kp=2.0)
    assert loop_signature(cfg, tuned) == loop_signature(cfg, lp)  # same samples ...
    assert result_signature(cfg, tuned) != result_signature(cfg, lp)  # ... other verdict
    raw["loops"][0]["window_s"] = 120
    longer = parse_config(raw)
    assert loop_signature(longer, longer.loops[0]) != loop_signature(cfg, lp)
