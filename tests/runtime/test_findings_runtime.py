"""The engineer's findings in a running gateway, in memory: read at start, exported, compared
with the verdict each loop had on the finding's day; a reload (SIGHUP) with a missing file
keeps the findings, one with bad rows skips them; and after a restart the verdicts compared
come back from the verdict history alone (the state file removed). (A real process
SIGKILLed: tests/e2e/test_findings_sigkill.py.)"""

from __future__ import annotations

import asyncio
import datetime as dt
import logging
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from deploy_support import require_tool, run
from memory_harness import FAKE, mconfig, mloop
from prometheus_client import CollectorRegistry, generate_latest
from reliability_helpers import until

from gateway.config import parse_config
from gateway.core.findings import day_start
from gateway.inputs.memory import memory_device
from gateway.runtime.gateway import Gateway

TODAY = dt.date.today()
YESTERDAY = TODAY - dt.timedelta(days=1)
NOON = dt.datetime.combine(YESTERDAY, dt.time(12)).timestamp()  # yesterday's calls


def _rows(n: int) -> list[list[float]]:
    """A swings (the fake analysis calls it stiction), B holds still (not oscillating)."""
    return [[50.0 + (10.0 if k % 10 < 5 else -10.0), 20.0, 50.0, 20.0] for k in range(n)]


def _config(tmp_path: Path) -> Any:
    raw = mconfig([memory_device("plc", _rows(200), poll_interval_s=0.02, repeat=True)],
                  [mloop("A", "plc", 0, 0, window_s=0.4), mloop("B", "plc", 2, 20,
                                                               window_s=0.4)],
                  state_file=str(tmp_path / "gw.state"), persist_interval_s=3600)
    raw["findings"] = str(tmp_path / "findings.csv")
    return parse_config(raw, str(tmp_path / "gw.yaml"))


def _gateway(cfg: Any, registry: CollectorRegistry) -> Gateway:
    return Gateway(cfg, registry=registry, analyze=FAKE, serve_http=False, persist=True,
                   executor=lambda: ThreadPoolExecutor(1))


def _count(registry: CollectorRegistry, verdict: str, finding: str) -> float | None:
    return registry.get_sample_value("stiction_findings_total",
                                     {"verdict": verdict, "finding": finding})


def test_findings_are_exported_reloaded_and_survive_a_restart(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    findings = tmp_path / "findings.csv"
    findings.write_text(f"loop,date,finding,fd,fs,by,note\n"
                        f"A,{YESTERDAY},stiction,2,3,J. Doe,packing tightened\n"
                        f"B,{YESTERDAY},ok,,,J. Doe,\n")
    cfg = _config(tmp_path)
    r1 = CollectorRegistry()

    async def first() -> str:
        async with _gateway(cfg, r1) as gw:
            await until(lambda: gw.pollers[0].good_polls >= 30)
            await gw.scheduler.run_round(now=lambda: NOON)
            assert _count(r1, "stiction", "stiction") == 1.0
            assert _count(r1, "not_oscillating", "ok") == 1.0
            assert r1.get_sample_value("stiction_loop_finding",
                                       {"loop": "A", "finding": "stiction"}) == 1.0
            assert r1.get_sample_value("stiction_loop_finding_timestamp_seconds",
                                       {"loop": "A"}) == day_start(YESTERDAY)
            text = generate_latest(r1).decode()
            findings.unlink()  # a reload without the file: the findings stay
            assert await gw.reload(cfg)
            assert _count(r1, "stiction", "stiction") == 1.0
            assert r1.get_sample_value("stiction_findings_problems") == 1.0
            findings.write_text(f"loop,date,finding\nA,{YESTERDAY},stiction\n"
                                f"A,{TODAY},ok\nZ,{TODAY},ok\n")  # a bad row: skipped
            assert await gw.reload(cfg)
            assert _count(r1, "stiction", "ok") == 1.0  # today began with yesterday's call
            assert r1.get_sample_value("stiction_loop_finding",
                                       {"loop": "A", "finding": "ok"}) == 1.0
            assert r1.get_sample_value("stiction_loop_finding",
                                       {"loop": "B", "finding": "none"}) == 1.0
            assert r1.get_sample_value("stiction_findings_problems") == 1.0
            await until(lambda: gw.pollers[0].good_polls >= 5)  # polling goes on
            return text

    text = asyncio.run(asyncio.wait_for(first(), 60))
    log = caplog.text
    assert "findings.csv not read; keeping the 2 finding(s) read before" in log
    assert "line 4: loop Z: column 'loop': no loop 'Z' in the config (row skipped)" in log
    assert (tmp_path / "gw.verdicts").exists()
    (tmp_path / "gw.state").unlink()  # only the verdict history can tell yesterday's calls
    r2 = CollectorRegistry()

    async def second() -> None:
        async with _gateway(_config(tmp_path), r2):
            assert _count(r2, "stiction", "stiction") == 1.0
            assert _count(r2, "stiction", "ok") == 1.0

    asyncio.run(asyncio.wait_for(second(), 60))
    promtool = require_tool("promtool", "prometheus")
    r = run([promtool, "check", "metrics"], input=text)
    assert (r.returncode, r.stdout + r.stderr) == (0, "")
