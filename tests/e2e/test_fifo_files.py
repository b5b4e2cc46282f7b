"""A FIFO where the findings file (and the state file) belongs, against the real commands
(issue 38 item 3): on 5c94178 ``check-config`` and ``run`` hung on it at start (the read
waited for a writer that never came). Now each says what the path is and goes on:
check-config passes (a findings file is never an error of the config; a FIFO as the state
file is), run starts without findings, a SIGHUP reload completes and SIGTERM ends it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from memory_harness import mconfig, mloop
from reliability_helpers import start_gateway, stop, wait_log

from bench._net import free_port
from gateway.inputs.memory import memory_device

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]


def _config(tmp_path: Path, state: str = "gw.state") -> Path:
    raw = mconfig([memory_device("plc", [[50.0, 20.0]] * 20, poll_interval_s=0.05,
                                 repeat=True)],
                  [mloop("A", "plc", 0, 0, window_s=1.0)],
                  state_file=str(tmp_path / state), persist_interval_s=3600)
    raw["metrics"]["listen"] = f"127.0.0.1:{free_port()}"
    raw["modbus_server"]["listen"] = f"127.0.0.1:{free_port()}"
    raw["findings"] = "findings.csv"
    path = tmp_path / "gw.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def test_check_config_answers_on_a_fifo(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "findings.csv")
    cfg = _config(tmp_path)
    cli = [sys.executable, "-m", "gateway.cli", "check-config"]
    try:
        r = subprocess.run([*cli, str(cfg)], capture_output=True, text=True, timeout=60,
                           check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("check-config hung on a FIFO as its findings file")
    assert r.returncode == 0, r.stderr
    assert (f"{tmp_path / 'findings.csv'}: cannot read: is a FIFO (named pipe), not a file: "
            "name a file") in r.stderr
    os.mkfifo(tmp_path / "fifo.state")
    cfg = _config(tmp_path, "fifo.state")
    try:
        r = subprocess.run([*cli, str(cfg)], capture_output=True, text=True, timeout=60,
                           check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("check-config hung on a FIFO as its state file")
    assert r.returncode == 2
    assert "gateway: key 'state_file'" in r.stderr and "is a FIFO (named pipe)" in r.stderr


def test_run_starts_reloads_and_stops_with_a_fifo_as_its_findings(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "findings.csv")
    cfg = _config(tmp_path)
    log = tmp_path / "gw.log"
    gw = start_gateway(cfg, log)
    try:
        wait_log(log, "gateway running")
        text = wait_log(log, "findings: ")
        assert "is a FIFO (named pipe), not a file" in text
        for n in (1, 2):  # the reload's lock is free again: the next one runs too
            gw.send_signal(signal.SIGHUP)
            deadline = time.monotonic() + 60
            while log.read_text().count("reloaded ") < n:
                assert time.monotonic() < deadline, log.read_text()
                time.sleep(0.1)
    finally:
        status = stop(gw, limit_s=30)
    assert status == 0, log.read_text()
    assert "gateway stopped" in log.read_text()
