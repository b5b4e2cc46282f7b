"""The poller's reliability rules, in memory: literal rows, scripted failures, a fake clock.

Each test drives ``DevicePoller.tick`` by hand (tests/support/memory_harness.py), so every
rule is checked poll by poll: gaps and qualities, stale flags, reconnecting with capped
backoff (and a longer one after a refused login), one log line per outage and per failing
block, the metrics. Missed ticks need the real schedule: the last test runs the poll loop.
"""

from __future__ import annotations

import asyncio
import logging

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop, wiggle

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.inputs.memory import memory_device
from gateway.runtime.reload import build_runtime

G, B, N, M = Quality.GOOD, Quality.BAD, Quality.NO_COMM, Quality.MISSING
CAP = 0.5  # gateway.reconnect_max_s


def harness(*devices: dict[str, object], loops: list[dict[str, object]]) -> Harness:
    return Harness(parse_config(mconfig(list(devices), loops), "<test>"))


def poller_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "gateway.poller"]


def test_a_dead_device_is_gaps_stale_after_three_polls_and_retried_with_backoff(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    h = harness(memory_device("plc", wiggle(100, 2), poll_interval_s=0.1),
                loops=[mloop("A", "plc", 0, 0)])
    src = h.source("plc")
    src.down = "connect"

    async def go() -> list[bool]:
        stale = []
        for _ in range(50):  # 5 s of polls at 0.1 s
            await h.tick()
            stale.append(bool(h.store.stale[0]))
        return stale

    stale = asyncio.run(go())
    _t, op, _pv, q = h.window("A")
    assert (q == N).all() and np.isnan(op).all()  # gaps, never zeros
    assert stale == [False] * 3 + [True] * 47
    # stale because its device is down: device_down (issue 23: one device alert, not one
    # LoopStale per loop), with the reason in the device's metric
    assert h.block("A")[0] == 9
    assert h.metric("stiction_loop_verdict", loop="A", verdict="device_down") == 1.0
    assert h.metric("stiction_loop_verdict", loop="A", verdict="stale") == 0.0
    assert h.metric("stiction_device_up", device="plc") == 0.0
    assert h.metric("stiction_device_down_reason", device="plc",
                    reason="no connection") == 1.0
    # backoff: several attempts, fewer than polls, never more than CAP apart
    assert 5 <= src.connects < 40
    assert h.metric("stiction_poll_errors_total", device="plc", kind="connect") == src.connects
    assert h.poller("plc").backoff.ceiling() == CAP
    assert poller_lines(caplog) == [
        "device plc: down (no connection): device plc: cannot connect (connect, scripted); "
        "retrying with backoff up to 0.5 s"]


def test_recovery_is_logged_once_and_resets_the_backoff(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    h = harness(memory_device("plc", wiggle(200, 2), poll_interval_s=0.1),
                loops=[mloop("A", "plc", 0, 0)])
    src, p = h.source("plc"), h.poller("plc")

    async def go() -> None:
        await h.tick(5)
        src.silent = True  # connected, but every read times out
        await h.tick(20)
        src.silent = False
        await h.tick(20)

    asyncio.run(go())
    _t, _op, _pv, q = h.window("A")
    assert q[:5].tolist() == [G] * 5 and q[5] == N and q[-1] == G
    assert p.up is True and p.backoff.attempt == 0 and p.reconnects >= 1
    assert not h.store.stale[0]
    assert h.metric("stiction_device_up", device="plc") == 1.0
    lines = poller_lines(caplog)
    assert len(lines) == 2
    assert lines[0].startswith("device plc: down (no answer)")
    assert lines[1] == "device plc: recovered"
    assert h.metric("stiction_device_down_reason", device="plc", reason="no answer") is None


def test_a_refused_login_is_retried_less_often() -> None:
    h = harness(memory_device("dcs", wiggle(10, 2), poll_interval_s=0.1),
                memory_device("plc", wiggle(10, 2), poll_interval_s=0.1),
                loops=[mloop("A", "dcs", 0, 0), mloop("B", "plc", 0, 20)])
    h.source("dcs").down = "auth"
    h.source("plc").down = "connect"
    asyncio.run(h.tick(650))  # a minute and 5 s: the second login is due within 30-60 s
    auth, refused = h.source("dcs").connects, h.source("plc").connects
    assert h.poller("dcs").backoff.ceiling("auth") == 60.0
    assert h.poller("plc").backoff.ceiling("connect") == CAP
    assert 2 <= auth < 20 < refused  # retried, but not every half second: no lock-out


def test_a_failing_block_is_gaps_for_its_points_only(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    h = harness(memory_device("plc", wiggle(100, 4), poll_interval_s=0.1),
                loops=[mloop("OK", "plc", 0, 0), mloop("EXC", "plc", 2, 20)])
    src = h.source("plc")

    async def go() -> None:
        await h.tick(3)
        src.failing_blocks = {"holding 200+4": [2, 3]}
        await h.tick(10)
        src.failing_blocks = {}
        await h.tick(3)

    asyncio.run(go())
    assert (h.window("OK")[3] == G).all()
    q = h.window("EXC")[3]
    assert q.tolist() == [G] * 3 + [N] * 10 + [G] * 3
    assert h.metric("stiction_poll_errors_total", device="plc", kind="exception") == 10
    assert h.metric("stiction_device_up", device="plc") == 1.0
    assert poller_lines(caplog) == [
        "device plc: holding 200+4: exception code 2; its points are gaps until it answers",
        "device plc: holding 200+4 answering again"]


def test_implausible_values_are_bad_not_stale_and_logged_on_change(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    rows = [[50.0, np.nan, 50.0, 150.0, 50.0, 20.0]] * 5 + [[50.0, 20.0] * 3] * 5
    raw = mconfig([memory_device("plc", rows, poll_interval_s=0.1)],
                  [mloop("NANL", "plc", 0, 0), mloop("RANGE", "plc", 2, 20),
                   mloop("OK", "plc", 4, 40)])
    raw["loops"][1]["pv"]["range"] = [0, 100]
    h = Harness(parse_config(raw, "<test>"))
    asyncio.run(h.tick(10))
    assert h.window("NANL")[3].tolist() == [B] * 5 + [G] * 5
    assert h.window("RANGE")[3].tolist() == [B] * 5 + [G] * 5
    assert (h.window("OK")[3] == G).all()
    assert not h.store.stale.any()  # the device answered: bad values are not stale
    lines = poller_lines(caplog)
    assert len(lines) == 2 and lines[1] == "device plc: values plausible again"
    assert lines[0].startswith("device plc: implausible values at NANL.pv, RANGE.pv (bad "
                               "samples until they are plausible) - NANL pv: nan is not a "
                               "number; the address is likely off by one")
    assert "; RANGE pv: 150 is outside its range 0..100: the address, type, word order " \
        "or scale is likely wrong, or the range" in lines[0]


def test_an_op_read_off_by_one_is_implausible_with_its_cause_in_the_log(
        caplog: pytest.LogCaptureFixture) -> None:
    """Issue 23: an off-by-one float32 OP read -2.5e17 (op_range 0-100) and the poller took
    it as GOOD; so would 3,000 %. Now both are BAD, and the one log line names the point,
    its tag-list line and the likely cause; 104 % (a DCS driving OP past its span) is
    not."""
    caplog.set_level(logging.INFO, logger="gateway")
    rows = [[-2.5e17, 20.0, 3000.0, 20.0, 104.0, 20.0]] * 5
    raw = mconfig([memory_device("plc", rows, poll_interval_s=0.1)],
                  [mloop("OFF", "plc", 0, 0), mloop("SCALE", "plc", 2, 20),
                   mloop("OK", "plc", 4, 40)])
    h = Harness(parse_config(raw, "<test>"))
    asyncio.run(h.tick(5))
    assert h.window("OFF")[3].tolist() == [B] * 5
    assert h.window("SCALE")[3].tolist() == [B] * 5
    assert (h.window("OK")[3] == G).all()
    (line,) = poller_lines(caplog)  # once, not per poll
    assert line.startswith("device plc: implausible values at OFF.op, SCALE.op")
    assert "OFF op: -2.5e+17 is beyond 1e+15: register garbage; the address is likely " \
        "off by one" in line
    assert "SCALE op: 3000 is outside op_range 0..100 (OP is % of valve span, 10% of it " \
        "allowed beyond)" in line


def test_poll_requests_metric_counts_what_the_source_sent() -> None:
    h = harness(memory_device("plc", wiggle(10, 2), poll_interval_s=0.1),
                loops=[mloop("A", "plc", 0, 0)])
    asyncio.run(h.tick(7))
    assert h.metric("stiction_poll_requests_total", device="plc") == 7  # 1 per memory read
    assert h.metric("stiction_poll_duration_seconds_count", device="plc") == 7


def test_a_hanging_source_is_cut_off_by_the_hard_limit() -> None:
    h = harness(memory_device("plc", wiggle(10, 2), poll_interval_s=0.1),
                loops=[mloop("A", "plc", 0, 0)])
    p, src = h.poller("plc"), h.source("plc")
    p.guard_s = 0.05
    src.hang_s = 5.0

    async def go() -> float:
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        await p.tick()
        return loop.time() - t0

    assert asyncio.run(go()) < 1.0
    assert h.metric("stiction_poll_errors_total", device="plc", kind="timeout") == 1
    assert h.window("A")[3].tolist() == [N]


def test_missed_ticks_become_gap_rows_in_time_order() -> None:
    """The real poll loop (real clock, 20 ms period): a read that takes three periods
    costs three missed ticks, each recorded as a gap row, not made up in a burst."""
    cfg = parse_config(mconfig([memory_device("plc", wiggle(50, 2), poll_interval_s=0.02)],
                               [mloop("A", "plc", 0, 0, window_s=2.0)]), "<test>")
    rt = build_runtime(cfg, wall=0.0)
    p = rt.pollers[0]
    src = p.source

    async def go() -> None:
        task = asyncio.create_task(p.run())
        await asyncio.sleep(0.1)
        src.hang_s = 0.07  # type: ignore[attr-defined]
        await asyncio.sleep(0.01)
        src.hang_s = 0.0  # type: ignore[attr-defined]
        await asyncio.sleep(0.15)
        p.request_stop()
        await task

    asyncio.run(go())
    t, _op, _pv, q = rt.groups[0].bank.series([0])
    assert p.missed_ticks >= 2
    assert int((q == N).sum()) == p.missed_ticks
    assert (np.diff(t) >= 0).all()  # one row per sample time, in order


def test_a_device_refusing_every_request_is_down_with_the_reason_its_loops_device_down(
        caplog: pytest.LogCaptureFixture) -> None:
    """Issue 23, item 1: a PLC that answers every request with exception 10 (device
    unit_id 5, the PLC serves 1) looked healthy: stiction_device_up 1, one block line, then
    every loop stale (a LoopStale alert each). Now the device is down, the reason in a
    label and in the one log line, in the same words; its loops are device_down."""
    caplog.set_level(logging.INFO, logger="gateway")
    loops = [mloop(f"L{k:03d}", "plc", 2 * k, 20 * k) for k in range(100)]
    h = harness(memory_device("plc", wiggle(50, 200), poll_interval_s=0.1), loops=loops)
    src = h.source("plc")
    words = "unit id 5 not served"
    src.refused = (words, "holding 0+125: gateway path unavailable (exception 10): unit id 5 "
                          "is not served by the PLC; set the device's unit_id")

    async def go() -> None:
        await h.tick(3)
        src.refused = None
        await h.tick(2)  # it answers again (the unit id fixed)
        src.refused = (words, src_message)
        await h.tick(10)

    src_message = src.refused[1]
    asyncio.run(go())
    assert h.metric("stiction_device_up", device="plc") == 0.0
    assert h.metric("stiction_device_down_reason", device="plc", reason=words) == 1.0
    assert h.metric("stiction_poll_refused_requests_total", device="plc",
                    exception=words) == 13
    names = [h.store.verdict_name(i) for i in range(100)]
    assert names == ["device_down"] * 100  # not 100 stale loops
    assert h.metric("stiction_loop_verdict", loop="L042", verdict="stale") == 0.0
    assert (h.window("L000")[3][-10:] == N).all()
    lines = poller_lines(caplog)
    assert lines == [
        f"device plc: down ({words}): device plc: {src_message}; polling on; its loops "
        "are device_down", "device plc: recovered",
        f"device plc: down ({words}): device plc: {src_message}; polling on; its loops "
        "are device_down"]
