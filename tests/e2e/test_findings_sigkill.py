"""The findings against a real process (issue 30): ``stiction-gateway run`` reads the
findings at start and on SIGHUP (a missing file keeps what it had, a bad row is skipped),
and the verdicts compared with them survive a SIGKILL: the history the killed process
wrote is what the next start compares with, even with the state file gone."""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import re
import signal
import time
from pathlib import Path

import pytest
import yaml
from memory_harness import FAKE, FakeTime, Harness, mconfig, mloop
from reliability_helpers import scrape, sigkill, start_gateway, stop, wait_log

from bench._net import free_port
from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile.format import snapshot, write_state

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]
YESTERDAY = dt.date.today() - dt.timedelta(days=1)
NOON = dt.datetime.combine(YESTERDAY, dt.time(12)).timestamp()


def _raw(tmp_path: Path, port: int) -> dict:  # type: ignore[type-arg]
    rows = [[50.0 + (10.0 if k % 10 < 5 else -10.0), 20.0] for k in range(100)]
    raw = mconfig([memory_device("plc", rows, poll_interval_s=0.05, repeat=True)],
                  [mloop("A", "plc", 0, 0, window_s=1.0)],
                  state_file=str(tmp_path / "gw.state"), persist_interval_s=0.3)
    raw["metrics"]["listen"] = f"127.0.0.1:{port}"
    raw["findings"] = "findings.csv"
    return raw


def _value(port: int, line_start: str) -> float | None:
    for line in scrape(port).splitlines():
        if line.startswith(line_start):
            return float(line.rsplit(" ", 1)[1])
    return None


def _wait_value(port: int, line_start: str, want: float, limit_s: float = 30) -> None:
    deadline = time.monotonic() + limit_s
    got = None
    while time.monotonic() < deadline:
        with contextlib.suppress(Exception):
            got = _value(port, line_start)
            if got == want:
                return
        time.sleep(0.1)
    raise AssertionError(f"{line_start}: {got}, expected {want}")


def test_findings_and_their_verdicts_survive_sigkill(tmp_path: Path) -> None:
    port = free_port()
    raw = _raw(tmp_path, port)
    cfg_path = tmp_path / "gw.yaml"
    cfg_path.write_text(yaml.safe_dump(raw))
    # yesterday the gateway called A sticky: a state file holding that call
    h = Harness(parse_config(raw, str(cfg_path)), time=FakeTime(wall=NOON))

    async def called() -> None:
        await h.tick(30)
        h.analyse(FAKE)

    asyncio.run(called())
    assert str(h.store.results[0].assessment.verdict) == "stiction"
    header, arrays = snapshot(h.config, h.runtime.groups, h.store, wall=NOON, proc=0.0)
    write_state(tmp_path / "gw.state", header, arrays)
    (tmp_path / "findings.csv").write_text(f"loop,date,finding\nA,{YESTERDAY},stiction\n")
    total = 'stiction_findings_total{finding="stiction",verdict="stiction"}'
    log = tmp_path / "gw.log"
    gw = start_gateway(cfg_path, log)
    try:
        wait_log(log, "gateway running", 120)
        _wait_value(port, total, 1.0)  # the restored call, compared
        deadline = time.monotonic() + 20
        while not (tmp_path / "gw.verdicts").exists() and time.monotonic() < deadline:
            time.sleep(0.05)  # the history written within persist_interval_s
        time.sleep(0.4)
        sigkill(gw)
    finally:
        stop(gw)
    (tmp_path / "gw.state").unlink()  # only the verdict history knows yesterday's call now
    gw = start_gateway(cfg_path, log)
    try:
        wait_log(log, "verdict history", 120)
        _wait_value(port, total, 1.0)
        # SIGHUP with the findings file gone: the findings stay, one problem counted
        (tmp_path / "findings.csv").unlink()
        gw.send_signal(signal.SIGHUP)
        _wait_value(port, "stiction_findings_problems ", 1.0)
        assert _value(port, total) == 1.0
        # SIGHUP with a bad row beside a good one: the good one counts, the bad is named
        (tmp_path / "findings.csv").write_text(
            f"loop,date,finding\nA,{YESTERDAY},stiction\nA,{dt.date.today()},ok\n"
            f"A,{YESTERDAY},broken\n")
        gw.send_signal(signal.SIGHUP)
        _wait_value(port, 'stiction_findings_total{finding="ok",verdict="stiction"}', 1.0)
        text = wait_log(log, "broken")
        assert re.search(r"findings\.csv: line 4: loop A: column 'finding': must be one of "
                         r"stiction, deadband, ok, other, was 'broken' \(row skipped\)", text)
        assert gw.poll() is None  # running throughout
    finally:
        assert stop(gw) == 0
    assert "findings.csv not read; keeping the 1 finding(s) read before" in log.read_text()
