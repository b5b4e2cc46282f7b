"""A loop's ``position:`` through the gateway without a socket (memory device, fake clock):
polled with OP and PV into a third signal of its window, handed to the analysis (the verdict
measured from the valve's travel), its latest value and sample quality exported; a loop
whose position is BAD keeps OP and PV's diagnosis; a loop without one is as before."""

from __future__ import annotations

import asyncio
import logging

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop
from valve_loops import run_loops

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.runtime.scheduler import log_verdict_change
from gateway.wire.results import VERDICT_CODES, decode_block
from stiction import Verdict
from stiction.diagnosis.travel import BY_OP_PV, BY_TRAVEL, MEASURED, NOT_USED
from stiction.models.valves import KanoValve

N = 1500


@pytest.fixture(scope="module")
def harness() -> Harness:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, samples=N + 500, pv_noise=0.05,
                     position_noise=0.05)
    rows = np.column_stack((r.op, r.pv, r.position, np.full(N, np.nan), r.op, r.pv,
                            100.0 - r.position))  # D: a position wired inverted
    devices = [{"name": "plc", "protocol": "memory", "poll_interval_s": 1.0, "timeout_s": 1.0,
                "values": rows.tolist()}]
    loops = [mloop("A", "plc", 0, 0, window_s=N, op_range=[0, 100], position={"column": 2}),
             mloop("B", "plc", 4, 32, window_s=N, op_range=[0, 100]),
             mloop("C", "plc", 4, 64, window_s=N, op_range=[0, 100], position={"column": 3}),
             mloop("D", "plc", 0, 96, window_s=N, op_range=[0, 100], position={"column": 6})]
    raw = mconfig(devices, loops)
    raw["modbus_server"]["block_registers"] = 32  # the extended block: +28 position use
    h = Harness(parse_config(raw, "t"))
    asyncio.run(h.tick(N))
    h.analyse("stiction:analyze")
    return h


def _assessment(h: Harness, loop: str):  # type: ignore[no-untyped-def]
    res = h.store.results[h.store.index[loop]]
    assert res is not None
    return res.assessment


def test_a_loop_with_its_position_is_decided_by_the_travel(harness: Harness) -> None:
    a = _assessment(harness, "A")
    assert a.verdict == Verdict.STICTION
    assert MEASURED in a.reason
    assert next(e.note for e in a.evidence if e.test == "travel").startswith(BY_TRAVEL)
    assert harness.metric("stiction_loop_band_ratio", loop="A") == pytest.approx(0.05, rel=0.1)
    assert harness.metric("stiction_loop_jump_ratio", loop="A") == pytest.approx(0.01, rel=0.1)
    block = decode_block(harness.block("A"))
    assert block["code"] == VERDICT_CODES[Verdict.STICTION]
    assert block["jump_percent"] == pytest.approx(1.0, rel=0.1)


def test_position_and_its_quality_are_exported(harness: Harness) -> None:
    assert harness.metric("stiction_loop_position_quality", loop="A") == Quality.GOOD
    assert harness.metric("stiction_loop_position_percent", loop="A") is not None
    assert harness.metric("stiction_loop_position_quality", loop="C") == Quality.BAD
    assert harness.metric("stiction_loop_position_percent", loop="C") is None
    assert harness.metric("stiction_loop_position_quality", loop="B") is None


def test_a_bad_position_keeps_the_op_pv_diagnosis(harness: Harness) -> None:
    b, c = _assessment(harness, "B"), _assessment(harness, "C")
    assert c.verdict == b.verdict != Verdict.BAD_DATA
    assert c.reason.startswith(b.reason)  # and says the position was not used, and why
    assert f"{NOT_USED}: position unusable" in c.reason.removeprefix(b.reason)
    assert c.position_use == "could_not_tell" and b.position_use is None
    assert next(e.note for e in c.evidence if e.test == "travel").startswith(BY_OP_PV)
    assert all(e.test != "travel" for e in b.evidence)


def test_what_became_of_the_position_is_in_a_register_a_metric_and_the_journal(
        harness: Harness, caplog: pytest.LogCaptureFixture) -> None:
    """Issue 35: a position that is not used shows in register +28, in the metric
    stiction_loop_position_use and in a journal line, not only in the reason."""
    uses = {n: _assessment(harness, n).position_use for n in "ABCD"}
    assert uses == {"A": "used", "B": None, "C": "could_not_tell", "D": "not_a_position"}
    assert [decode_block(harness.block(n))["position_use"] for n in "ABCD"] == [1, 0, 2, 3]
    for n, use in uses.items():
        for u in ("used", "could_not_tell", "not_a_position"):
            want = None if use is None else float(u == use)
            assert harness.metric("stiction_loop_position_use", loop=n, use=u) == want
    with caplog.at_level(logging.WARNING, logger="gateway"):
        log_verdict_change("D", None, _assessment(harness, "D"))
        log_verdict_change("A", None, _assessment(harness, "A"))
    said = [r.getMessage() for r in caplog.records if "position" in r.getMessage()]
    assert said == ["loop D: its valve position is not used (not a position): OP and PV "
                    "decide; see its reason"]


def test_the_window_holds_the_position(harness: Harness) -> None:
    for g in harness.runtime.groups:
        pos = g.bank.positions(range(len(g.configs)))
        assert pos is not None
        a, c = g.loops.index("A"), g.loops.index("C")
        assert np.isfinite(pos[a]).all()
        assert np.isnan(pos[c]).all()
        assert np.isnan(pos[g.loops.index("B")]).all()
