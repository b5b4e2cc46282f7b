"""Restarts lose nothing, in memory: windows and assessments written by the state-file
output come back, loop by loop where the config still matches (a loop whose window changed
starts fresh), with the downtime as a gap of exactly the samples missed; the result
registers show the restored assessment at once. A corrupt file does not stop a gateway.
(A real process SIGKILLed: tests/e2e/test_state_sigkill.py; bad files set aside:
tests/outputs/test_statefile.py.)"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop, wiggle
from prometheus_client import CollectorRegistry
from reliability_helpers import FAKE, until

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.inputs.memory import memory_device
from gateway.outputs import statefile
from gateway.outputs.statefile import StateFile, read_state
from gateway.runtime.gateway import Gateway

POLL = 0.05


def _raw(state: Path, **gateway: Any) -> dict[str, Any]:
    return mconfig([memory_device("plc", wiggle(400, 4), poll_interval_s=POLL, repeat=True)],
                   [mloop("A", "plc", 0, 0), mloop("B", "plc", 2, 20)],
                   state_file=str(state), **gateway)


def test_windows_and_results_survive_a_restart(tmp_path: Path,
                                               caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    state = tmp_path / "state" / "gw.state"
    first = Harness(parse_config(_raw(state), "first"))
    # restart: same config for A, B's window changed (its PV scaled: other values)
    raw = _raw(state)
    raw["loops"][1]["pv"]["scale"] = 2.0

    async def go() -> tuple[Harness, StateFile]:
        await first.tick(60)
        first.analyse(FAKE)
        first.analyse(FAKE)
        await first.tick(1)
        await StateFile(first.runtime.binding(), wall=lambda: first.time.wall).save(
            final=True)  # as at a normal exit (after a kill, sequence numbers move on)
        first.time.advance(0.5)  # downtime: 10 samples missed
        second = Harness(parse_config(raw, "second"), time=first.time)
        sink = StateFile(second.runtime.binding(), wall=lambda: second.time.wall)
        await sink.start()  # restores
        # at once: A's verdict (the fake's not_oscillating: warming_up, its window not full)
        assert second.block("A")[0] == 8 and second.block("B")[0] == 0
        await second.tick(40)
        await sink.stop()
        return second, sink

    second, sink = asyncio.run(go())
    saved = first.window("A")
    restored = second.window("A")
    n = len(saved[0])
    assert n == 61
    for x, y in zip(saved, restored, strict=True):  # A: every saved sample is back
        np.testing.assert_array_equal(y[:n], x)
    # the downtime is a gap of exactly the missed samples (MISSING), then new samples
    q = restored[3][n:]
    assert q.tolist() == [Quality.MISSING] * 10 + [Quality.GOOD] * 40
    np.testing.assert_allclose(np.diff(restored[0]), POLL, atol=1e-5)  # a row per sample time
    # A's assessment came back (same seq, same reason); B (window changed) starts fresh
    a1, a2 = first.store.results[0], second.store.results[0]
    assert (a2.seq, a2.assessment.reason) == (a1.seq, a1.assessment.reason)
    assert second.store.results[1] is None
    q_b = second.window("B")[3]  # only samples of the new process (in A's bank)
    assert q_b.tolist() == [Quality.MISSING] * (n + 10) + [Quality.GOOD] * 40
    assert sink.report is not None and sink.report.gap_rows == 10
    assert any("restored 1 windows and 1 assessments; 1 loops start fresh" in r.getMessage()
               for r in caplog.records)
    header, _ = read_state(state)  # written again when the output stopped
    assert header["saved_wall"] == second.time.wall


@pytest.mark.timeout(60)
def test_gateway_starts_and_polls_with_a_corrupt_state_file(tmp_path: Path) -> None:
    state = tmp_path / "gw.state"
    state.write_bytes(b"PK\x03\x04 this is not what it seems" * 50)

    async def go() -> int:
        cfg = parse_config(_raw(state), "t")
        async with Gateway(cfg, registry=CollectorRegistry(), analyze=FAKE, serve_http=False,
                           persist=True, executor=lambda: ThreadPoolExecutor(1)) as gw:
            await until(lambda: gw.pollers[0].good_polls >= 5)
            return gw.pollers[0].good_polls

    assert asyncio.run(asyncio.wait_for(go(), 50)) >= 5
    assert len(list(tmp_path.glob("gw.state.corrupt-*"))) == 1
    header, _ = read_state(state)  # a fresh, good file was written at exit (no position in
    assert header["version"] == 1  # it: the version the release before version 2 reads)


def test_a_write_cancelled_at_stop_finishes_before_the_final_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Stopping cancels the periodic write while its thread writes on; the final write
    waits for it (the two once shared one temporary file: 'final write failed' in one run
    of the hostile test, or a torn file)."""
    state = tmp_path / "gw.state"
    harness = Harness(parse_config(_raw(state), "t"))
    inside: list[int] = []
    overlapped: list[bool] = []
    writing = threading.Event()
    real_write = statefile.write_state

    def slow_write(*args: Any) -> int:
        overlapped.append(bool(inside))
        inside.append(1)
        writing.set()
        try:
            time.sleep(0.3)
            return real_write(*args)
        finally:
            inside.pop()

    monkeypatch.setattr(statefile, "write_state", slow_write)

    async def go() -> dict[str, Any]:
        await harness.tick(10)
        sink = StateFile(harness.runtime.binding(), wall=lambda: harness.time.wall)
        periodic = asyncio.create_task(sink.save())
        assert await asyncio.to_thread(writing.wait, 5)  # its thread is writing
        periodic.cancel()  # as stop() cancels the periodic task
        with contextlib.suppress(asyncio.CancelledError):
            await periodic
        await sink.save(final=True)
        return read_state(state)[0]

    header = asyncio.run(go())
    assert overlapped == [False, False]  # two writes, one after the other
    assert header["clean"] is True  # the final write is the file that stayed
