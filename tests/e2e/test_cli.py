"""The CLI life cycle: run + SIGTERM, plc-sim --write-gateway-config, a bounded demo, Ctrl-C."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
import yaml

from bench._net import free_port
from gateway.config import load_config
from gateway.core.points import Quality
from plcsim import load_sim_config

G, N = Quality.GOOD, Quality.NO_COMM
CLI = [sys.executable, "-m", "gateway.cli"]
ROOT = Path(__file__).resolve().parents[2]


def _wait_http(port: int, timeout: float = 20.0) -> str:
    deadline = time.monotonic() + timeout
    while True:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=2) as r:
                return str(r.read().decode())
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


@pytest.mark.timing  # exits within 5 s of SIGTERM: a wall-clock bound
def test_run_serves_and_stops_cleanly_on_sigterm(tmp_path: Path) -> None:
    """A gateway whose PLC is not there keeps running (device down), serves metrics, and
    exits 0 within a few seconds of SIGTERM."""
    raw = yaml.safe_load((ROOT / "configs" / "example.yaml").read_text())
    metrics_port = free_port()
    raw["metrics"]["listen"] = f"127.0.0.1:{metrics_port}"
    raw["modbus_server"]["listen"] = "127.0.0.1:0"
    for dev in raw["devices"]:
        dev["host"], dev["port"], dev["timeout_s"] = "127.0.0.1", free_port(), 0.2
    path = tmp_path / "gw.yaml"
    path.write_text(yaml.safe_dump(raw))
    proc = subprocess.Popen([*CLI, "run", "--config", str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        text = _wait_http(metrics_port)
        assert 'stiction_device_up{device="plc1"} 0.0' in text
        assert 'stiction_loop_verdict{loop="FIC101",verdict="none"} 1.0' in text
        # stale after 3 polls without a good sample: device_down, its device being down
        stale = 'stiction_loop_verdict{loop="FIC101",verdict="device_down"} 1.0'
        deadline = time.monotonic() + 10
        while stale not in text and time.monotonic() < deadline:
            time.sleep(0.5)
            text = _wait_http(metrics_port)
        assert stale in text
        assert 'stiction_device_down_reason{device="plc1",reason="no connection"} 1.0' in text
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=15)
        assert proc.returncode == 0, out
        assert time.monotonic() - t0 < 5.0
        assert "device plc1: down (no connection)" in out
        assert "gateway stopping" in out
        assert "Traceback" not in out
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_plc_sim_writes_its_gateway_config(tmp_path: Path) -> None:
    out = tmp_path / "gw.yaml"
    res = subprocess.run([*CLI, "plc-sim", "--config", str(ROOT / "configs" / "plc-sim.yaml"),
                          "--write-gateway-config", str(out)], capture_output=True, text=True,
                         timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    gw = load_config(out)
    sim = load_sim_config(ROOT / "configs" / "plc-sim.yaml")
    assert [lp.name for lp in gw.loops] == [lp.name for lp in sim.loops]
    assert gw.devices[0].options.port == 5502
    assert gw.loops[1].process == "integrating"
    assert gw.loops[1].kp == 0.2


def test_demo_runs_bounded_and_prints_where_it_listens() -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    res = subprocess.run([*CLI, "demo", "--duration", "6"], capture_output=True, text=True,
                         timeout=90, check=False, env=env)
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "Prometheus metrics: http://127.0.0.1:" in out
    assert "Modbus result server: 127.0.0.1:" in out
    for name in ("FIC101", "LIC201", "TIC301", "FIC401", "PIC501", "U2.FIC101", "U2.TIC201"):
        assert name in out
    assert "plant groups: none yet" in out  # (the plant's windows fill in 30 s)
    assert "demo stopped" in out
    # nothing printed at exit (a pool shut down without joining it printed an ignored
    # "OSError: Bad file descriptor" traceback in about 2 of 5 runs)
    assert "Traceback" not in res.stderr, res.stderr
    assert "Exception ignored" not in res.stderr, res.stderr


def test_demo_stops_cleanly_on_ctrl_c() -> None:
    """Ctrl-C goes to the whole foreground process group, analysis workers included: the
    demo says it stopped, exits 0, and no process prints a traceback (each worker printed a
    KeyboardInterrupt traceback before the workers ignored SIGINT)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([*CLI, "demo"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 60
        seen = ""
        while "t =" not in seen and time.monotonic() < deadline:  # the first table: running
            seen += proc.stdout.readline()
        assert "t =" in seen
        time.sleep(4.0)  # an analysis round or more (3 s of wall time each at 40x)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, err
    assert "demo stopped" in out
    assert "Traceback" not in err, err
    assert "Exception ignored" not in err, err
