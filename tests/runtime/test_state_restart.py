"""Issue 6 item 4: the state file - restarts lose nothing.

* Round trip: windows and assessments written on exit are restored on start, loop by loop
  where the config still matches (a loop whose window changed starts fresh), with the
  downtime as a gap; the result registers show the restored assessment at once.
* SIGKILL of a real gateway process: the file on disk lags the kill by at most one
  ``persist_interval_s`` (+ one poll), and the next start restores it.
* Corrupt, truncated and foreign files are set aside with a warning, never a crash.
"""

from __future__ import annotations

import asyncio
import logging
import os
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from prometheus_client import CollectorRegistry
from reliability_helpers import (
    FAKE,
    ScriptedPlc,
    device,
    feed,
    loop,
    raw_config,
    read_codes,
    sim_loops,
    start_gateway,
    start_plc_sim,
    stop,
    until,
    wait_log,
)

from bench._net import free_port
from gateway.config import parse_config
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup, WindowBank
from gateway.inputs.base import Quality
from gateway.outputs.statefile import read_state, restore_state
from gateway.outputs.statefile.format import snapshot, write_state
from gateway.runtime.gateway import Gateway


def _wiggle(k: int, plc: ScriptedPlc) -> None:
    for a in (0, 4):
        plc.set(a, 50.0 + 10.0 * np.sin((k + a) / 5.0))
        plc.set(a + 2, 20.0 + np.cos((k + a) / 7.0))


def _raw(port: int, state: Path, **gateway: Any) -> dict[str, Any]:
    return raw_config([device("plc", port, poll=0.05)],
                      [loop("A", "plc", 0, 0), loop("B", "plc", 4, 20)],
                      state_file=str(state), **gateway)


@pytest.mark.timeout(60)
def test_windows_and_results_survive_a_restart(tmp_path: Path,
                                               caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    state = tmp_path / "state" / "gw.state"
    out: dict[str, Any] = {}

    async def go() -> None:
        plc = await ScriptedPlc(16).start()
        feeder = asyncio.create_task(feed(plc, 0.02, _wiggle))
        cfg = parse_config(_raw(plc.port, state, analysis_interval_s=0.5,
                                persist_interval_s=0.3), "first")
        async with Gateway(cfg, registry=CollectorRegistry(), analyze=FAKE,
                           serve_http=False, persist=True) as gw:
            await until(lambda: gw.scheduler.rounds >= 2 and gw.saves >= 2)
            bank = gw.pollers[0].groups[0].bank
        # after exit: the bank as it was when the final state was written
        out["saved"] = bank.series([0, 1])
        out["seq"] = [r.seq for r in gw.store.results]
        out["reason"] = gw.store.results[0].assessment.reason
        out["exit_wall"] = time.time()
        await asyncio.sleep(0.5)  # downtime: ~10 samples missed
        # restart: same config for A, B's window changed
        raw = _raw(plc.port, state, analysis_interval_s=1e6)
        raw["loops"][1]["window_s"] = 20.0
        cfg2 = parse_config(raw, "second")
        async with Gateway(cfg2, registry=CollectorRegistry(), analyze=FAKE,
                           serve_http=False, persist=True) as gw2:
            out["codes"] = await read_codes(gw2.result_port, {"A": 0, "B": 20})
            slots = {s.bank.loops: s.bank for s in gw2.pollers[0].groups}
            bank_a = slots[("A",)]
            await until(lambda: bank_a.count > len(out["saved"][0]) + 30)
            out["restored_a"] = bank_a.series([0])
            out["b_count"] = slots[("B",)].count
            out["seq2"] = [r.seq if r else None for r in gw2.store.results]
            out["reason2"] = gw2.store.results[0].assessment.reason
        feeder.cancel()
        await plc.stop()

    asyncio.run(asyncio.wait_for(go(), 50))
    t, op, _pv, q = out["saved"]
    n = len(t)
    assert n >= 20
    t2, op2, _pv2, q2 = out["restored_a"]
    np.testing.assert_array_equal(t2[:n], t)
    np.testing.assert_array_equal(op2[0][:n], op[0])
    np.testing.assert_array_equal(q2[0][:n], q[0])
    # the downtime is a gap of MISSING samples, then new samples follow
    gap = q2[0][n:]
    missing = int(np.argmax(gap != Quality.MISSING))
    assert 5 <= missing <= 20, missing
    assert (gap[missing:] == Quality.GOOD).sum() >= 5
    # A's assessment came back (same seq, same reason); B (window changed) starts fresh
    assert out["seq2"] == [out["seq"][0], None]
    assert out["reason2"] == out["reason"]
    assert out["codes"] == {"A": 1, "B": 0}  # before any analysis of the new process
    assert out["b_count"] <= len(t2) - n - missing + 2  # only samples of the new process
    assert any("restored 1 windows and 1 assessments; 1 loops start fresh" in r.getMessage()
               for r in caplog.records)


@pytest.mark.timeout(90)
def test_sigkill_loses_at_most_one_persist_interval(tmp_path: Path) -> None:
    interval, poll = 1.0, 0.1
    port = free_port()
    plc = start_plc_sim(tmp_path, port, loops=4, ts=poll)
    state = tmp_path / "gw.state"
    cfg = tmp_path / "gw.yaml"
    raw = raw_config([device("plc", port, poll=poll)], sim_loops(4, window_s=60.0),
                     state_file=str(state), persist_interval_s=interval)
    cfg.write_text(yaml.safe_dump(raw))
    log = tmp_path / "gw.log"
    try:
        gw = start_gateway(cfg, log)
        try:
            wait_log(log, "gateway running")
            deadline = time.monotonic() + 30
            while not state.exists() and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(2.0 + 0.37)  # a few writes, then kill somewhere between two
            kill_wall = time.time()
            os.kill(gw.pid, signal.SIGKILL)
            gw.wait(10)
        finally:
            stop(gw)
        _header, arrays = read_state(state)
        last = float(arrays["b0_t"][-1])
        lost = kill_wall - last
        n_good = int((arrays["b0_q"] == Quality.GOOD).all(axis=1).sum())
        print(f"\nSIGKILL: last saved sample {lost:.2f} s before the kill "
              f"(persist_interval_s {interval}, poll {poll}); {n_good} samples in the file")
        assert lost <= interval + poll + 0.3
        assert n_good >= 20
        # the next start restores it
        gw = start_gateway(cfg, log)
        try:
            text = wait_log(log, "restored 4 windows")
        finally:
            assert stop(gw) == 0
        assert "start fresh" in text
        assert not list(tmp_path.glob(".gw.state.tmp-*"))
    finally:
        stop(plc)


def _bank() -> tuple[Any, list[LoopGroup], ResultStore]:
    raw = raw_config([device("plc", 502)], [loop("A", "plc", 0, 0)])
    cfg = parse_config(raw, "t")
    bank = WindowBank(["A"], cfg.window_samples(cfg.loops[0]))
    zero = np.zeros(1, dtype=np.intp)
    return cfg, [LoopGroup("plc", bank, cfg.loops, zero, zero + 1, zero, 0.1)], ResultStore(["A"])


def _good_state(path: Path) -> None:
    cfg, banks, store = _bank()
    for k in range(30):
        banks[0].bank.append(float(k), np.array([1.0]), np.array([2.0]),
                             np.zeros(1, dtype=np.uint8))
    write_state(path, *snapshot(cfg, banks, store, wall=time.time(), proc=time.time()))


def _corrupt(path: Path) -> None:
    path.write_bytes(os.urandom(3000))


def _truncated(path: Path) -> None:
    _good_state(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _foreign(path: Path) -> None:
    with open(path, "wb") as f:
        np.savez(f, weights=np.ones(10))


def _wrong_version(path: Path) -> None:
    with open(path, "wb") as f:
        header = b'{"format": "stiction-gateway-state", "version": 99}'
        np.savez(f, header=np.frombuffer(header, dtype=np.uint8))


def _empty(path: Path) -> None:
    path.write_bytes(b"")


@pytest.mark.parametrize(("make", "kind"), [(_corrupt, "corrupt"), (_truncated, "corrupt"),
                                            (_empty, "corrupt"), (_foreign, "foreign"),
                                            (_wrong_version, "foreign")])
def test_bad_state_files_are_set_aside(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                       make: Any, kind: str) -> None:
    path = tmp_path / "gw.state"
    make(path)
    cfg, banks, store = _bank()
    report = restore_state(path, cfg, banks, store, wall=time.time(), time_scale=1.0)
    assert not path.exists()
    aside = list(tmp_path.glob(f"gw.state.{kind}-*"))
    assert len(aside) == 1 and report.set_aside == aside[0]
    assert banks[0].bank.count == 0 and report.restored_windows == 0
    assert any(r.levelname == "WARNING" and "starting fresh" in r.getMessage()
               for r in caplog.records)


@pytest.mark.timeout(60)
def test_gateway_starts_and_polls_with_a_corrupt_state_file(tmp_path: Path) -> None:
    state = tmp_path / "gw.state"
    state.write_bytes(b"PK\x03\x04 this is not what it seems" * 50)

    async def go() -> int:
        plc = await ScriptedPlc(16).start()
        cfg = parse_config(_raw(plc.port, state), "t")
        async with Gateway(cfg, registry=CollectorRegistry(), analyze=FAKE,
                           serve_http=False, persist=True) as gw:
            await until(lambda: gw.pollers[0].good_polls >= 5)
            polls = gw.pollers[0].good_polls
        await plc.stop()
        return polls

    assert asyncio.run(asyncio.wait_for(go(), 50)) >= 5
    assert len(list(tmp_path.glob("gw.state.corrupt-*"))) == 1
    header, _ = read_state(state)  # a fresh, good file was written at exit
    assert header["version"] == 1
