"""Issue 31, finding 1: a wall clock stepped back across a restart (an NTP correction after a
reboot). Main took the downtime as ``max(0, now - saved)``: after a clean stop, 30 s down
and the clock 1 h back, "downtime gap 0 samples" joined the samples before and after as one
contiguous run; after a SIGKILL the sequence numbers SCADA read went 11 -> 7. Each test
failed on main the day the issue was filed (3dfa8c7). In memory, with a fake clock; a real
process under a stepped clock: tests/e2e/test_clock_step.py.
"""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path
from typing import Any

import pytest
from memory_harness import FAKE, FakeTime, Harness, mconfig, mloop, wiggle

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.core.windows import analysis_segment
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import StateFile
from gateway.outputs.statefile.restore import UNKNOWN_DOWNTIME_ROWS

POLL = 0.1
BACK_S = 3600.0


def _raw(state: Path) -> dict[str, Any]:
    return mconfig([memory_device("plc", wiggle(400, 2), poll_interval_s=POLL, repeat=True)],
                   [mloop("A", "plc", 0, 0, window_s=20.0)], state_file=str(state),
                   analysis_interval_s=1.0, persist_interval_s=2.0)


def _restart(first: Harness, raw: dict[str, Any], down_s: float) -> Harness:
    """The next process: ``down_s`` later by the real clock, its wall clock 1 h back."""
    return Harness(parse_config(raw, "second"),
                   time=FakeTime(mono=first.time.mono + down_s,
                                 wall=first.time.wall + down_s - BACK_S))


def test_after_a_clean_stop_the_downtime_is_a_gap_when_the_clock_went_back(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Clean stop, 30 s down, the clock 1 h back: the samples before and after are never
    joined (a gap longer than the analysis bridges, main: none); the sequence number is the
    saved one (the file was the last write); one WARNING line and
    stiction_state_clock_back_seconds say the clock went back."""
    caplog.set_level(logging.INFO, logger="gateway")
    raw = _raw(tmp_path / "gw.state")
    first = Harness(parse_config(raw, "first"))

    async def go() -> tuple[Harness, StateFile]:
        await first.tick(39)
        first.analyse(FAKE)
        await StateFile(first.runtime.binding(), wall=lambda: first.time.wall).save(
            final=True)
        second = _restart(first, raw, 30.0)
        sink = StateFile(second.runtime.binding(), wall=lambda: second.time.wall,
                         metrics=second.metrics)
        await sink.start()
        await second.tick(11)
        await sink.stop()
        return second, sink

    second, sink = asyncio.run(go())
    _t, op, pv, q = second.window("A")
    assert q.tolist() == ([Quality.GOOD] * 39 + [Quality.MISSING] * UNKNOWN_DOWNTIME_ROWS
                          + [Quality.GOOD] * 11)
    seg, _ = analysis_segment(op, pv, q)
    assert len(seg) == 11  # the analysis sees the new samples only (main: 50, one run)
    assert sink.report is not None and sink.report.gap_rows == UNKNOWN_DOWNTIME_ROWS
    assert sink.report.clock_back_s == pytest.approx(BACK_S - 30.0)
    assert second.metric("stiction_state_clock_back_seconds") == pytest.approx(BACK_S - 30.0)
    a1, a2 = first.store.results[0], second.store.results[0]
    assert a1 is not None and a2 is not None and a2.seq == a1.seq
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1, warnings
    assert "the wall clock is 3570 s behind the file's last write" in warnings[0]
    assert "the downtime is unknown" in warnings[0]


def test_after_a_kill_sequence_numbers_never_go_backwards_when_the_clock_went_back(
        tmp_path: Path) -> None:
    """SIGKILL (the file lags what SCADA read by up to one persist interval), restart 5 s
    later with the clock 1 h back: each sequence number comes back past any the killed
    process published (main: 11 before the kill, 7 after, then 8 to 11 again with other
    content); the downtime is a gap."""
    raw = _raw(tmp_path / "gw.state")
    first = Harness(parse_config(raw, "first"))

    async def go() -> tuple[Harness, int]:
        await first.tick(20)
        for _ in range(6):
            first.analyse(FAKE)
            await first.tick(10)  # one analysis interval (1 s)
        await StateFile(first.runtime.binding(), wall=lambda: first.time.wall).save()
        for _ in range(2):  # published within the persist interval, lost by the kill
            first.analyse(FAKE)
            await first.tick(10)
        result = first.store.results[0]
        assert result is not None
        second = _restart(first, raw, 5.0)
        await StateFile(second.runtime.binding(), wall=lambda: second.time.wall,
                        metrics=second.metrics).start()
        return second, result.seq

    second, seen = asyncio.run(go())
    restored = second.store.results[0]
    assert seen == 8
    assert restored is not None and restored.seq > seen  # main: 7
    second.analyse(FAKE)
    after = second.store.results[0]
    assert after is not None and after.seq > restored.seq
    q = second.window("A")[3]
    assert q[-UNKNOWN_DOWNTIME_ROWS:].tolist() == [Quality.MISSING] * UNKNOWN_DOWNTIME_ROWS
    # the save was 2 s before the kill, the restart 5 s after it
    assert second.metric("stiction_state_clock_back_seconds") == pytest.approx(BACK_S - 7.0)


def test_with_the_clock_on_time_the_gap_is_the_downtime_and_no_clock_line(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The rule only applies when the clock is behind the file: a clock on time gives the
    exact gap (2 s down, 2.1 s since the last sample: 20 rows) and no warning, metric 0."""
    caplog.set_level(logging.INFO, logger="gateway")
    raw = _raw(tmp_path / "gw.state")
    first = Harness(parse_config(raw, "first"))

    async def go() -> StateFile:
        await first.tick(39)
        await StateFile(first.runtime.binding(), wall=lambda: first.time.wall).save(
            final=True)
        first.time.advance(2.0)  # 2 s down, the clock on time
        second = Harness(parse_config(raw, "second"), time=first.time)
        sink = StateFile(second.runtime.binding(), wall=lambda: second.time.wall,
                         metrics=second.metrics)
        await sink.start()
        assert second.metric("stiction_state_clock_back_seconds") == 0.0
        return sink

    sink = asyncio.run(go())
    assert sink.report is not None and sink.report.gap_rows == 20
    assert sink.report.clock_back_s == 0.0
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
