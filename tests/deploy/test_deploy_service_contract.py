"""What deploy/systemd/stiction-gateway.service promises systemd, checked against the real
`stiction-gateway run` without systemd: the test plays systemd's part of the notify protocol
(a datagram socket in $NOTIFY_SOCKET, $WATCHDOG_USEC) and sends SIGHUP like `ExecReload`.

- Type=notify: READY=1 arrives once the gateway serves (else `systemctl start` times out);
- WatchdogSec: WATCHDOG=1 arrives at least every WATCHDOG_USEC/2 (else systemd kills it);
- ExecReload=/bin/kill -HUP $MAINPID: RELOADING=1 then READY=1, and the process lives on
  (SIGHUP's default action would end it);
- SIGTERM: STOPPING=1 and exit status 0 (Restart=on-failure must not restart a clean stop).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import yaml
from deploy_support import UNIT, require, run
from test_deploy_live import GATEWAY, HEALTHY, TIME_SCALE

from bench._net import free_port

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]

WATCHDOG_S = 2.0


def _unit_seconds(key: str) -> float:
    for line in UNIT.read_text().splitlines():
        if line.startswith(f"{key}="):
            return float(line.split("=", 1)[1].removesuffix("s"))
    raise AssertionError(f"no {key} in the unit")


def _unit_watchdog_s() -> float:
    return _unit_seconds("WatchdogSec")


@pytest.fixture
def gateway_under_notify(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], socket.socket]]:
    r = run([GATEWAY, "plc-sim", "--help"]) if Path(GATEWAY).exists() else None
    require(r is not None and r.returncode == 0, f"{GATEWAY} has no plc-sim yet")
    python = Path(GATEWAY).with_name("python")
    if python.exists():
        r = run([str(python), "-c", "import stiction; stiction.analyze"])
        require(r.returncode == 0, "stiction.analyze is not there yet (analysis branch)")
    sim_cfg = {
        "listen": f"127.0.0.1:{free_port()}",
        "time_scale": TIME_SCALE,
        "loops": [{"name": HEALTHY, "scenario": "healthy", "noise": 0.02, "window_s": 600}],
    }
    (tmp_path / "sim.yaml").write_text(yaml.safe_dump(sim_cfg))
    r = run([GATEWAY, "plc-sim", "--config", str(tmp_path / "sim.yaml"),
             "--write-gateway-config", str(tmp_path / "gw.yaml")])  # fmt: skip
    assert r.returncode == 0, r.stderr
    gw = yaml.safe_load((tmp_path / "gw.yaml").read_text())
    gw["gateway"].update(time_scale=TIME_SCALE, state_file=str(tmp_path / "gw.state"))
    gw["metrics"]["listen"] = f"127.0.0.1:{free_port()}"
    gw["modbus_server"]["listen"] = f"127.0.0.1:{free_port()}"
    (tmp_path / "gw.yaml").write_text(yaml.safe_dump(gw))

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(tmp_path / "notify"))
    sock.settimeout(0.2)
    env = {
        **os.environ,
        "NOTIFY_SOCKET": str(tmp_path / "notify"),
        "WATCHDOG_USEC": str(int(WATCHDOG_S * 1e6)),
    }
    logs = (tmp_path / "sim.log").open("wb"), (tmp_path / "gw.log").open("wb")
    sim = subprocess.Popen(
        [GATEWAY, "plc-sim", "--config", str(tmp_path / "sim.yaml")],
        stdout=logs[0],
        stderr=subprocess.STDOUT,
    )
    proc = subprocess.Popen(
        [GATEWAY, "run", "--config", str(tmp_path / "gw.yaml")],
        stdout=logs[1],
        stderr=subprocess.STDOUT,
        env=env,
    )
    try:
        yield proc, sock
    finally:
        for p in (proc, sim):
            if p.poll() is None:
                p.kill()
                p.wait()
        for f in logs:
            f.close()
        sock.close()


Msgs = list[tuple[float, dict[str, str]]]


def _messages(sock: socket.socket, seconds: float, until: Callable[[Msgs], bool]) -> Msgs:
    """Notify datagrams (monotonic time, fields) received until ``until`` holds for them or
    ``seconds`` have passed."""
    out: Msgs = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not until(out):
        try:
            data = sock.recv(4096)
        except TimeoutError:
            continue
        fields = dict(line.split("=", 1) for line in data.decode().splitlines() if "=" in line)
        out.append((time.monotonic(), fields))
    return out


def _has(msgs: Msgs, key: str, value: str) -> bool:
    return any(f.get(key) == value for _, f in msgs)


def _first(msgs: Msgs, key: str, value: str | None = None) -> float:
    for t, fields in msgs:
        if key in fields and (value is None or fields[key] == value):
            return t
    raise AssertionError(f"no {key}={value or '*'} in {[f for _, f in msgs]}")


def test_unit_watchdog_leaves_room_for_the_test_period() -> None:
    assert _unit_watchdog_s() >= 10 * WATCHDOG_S / 2


def test_ready_watchdog_reload_and_stop(
    gateway_under_notify: tuple[subprocess.Popen[bytes], socket.socket],
) -> None:
    proc, sock = gateway_under_notify
    start = time.monotonic()
    # READY=1 came after 3.7 s on a quiet box, after over 15 s with the suite's four workers
    # on two cores: wait up to half the unit's TimeoutStartSec (systemd fails the start there)
    msgs = _messages(
        sock,
        _unit_seconds("TimeoutStartSec") / 2,
        lambda m: _has(m, "READY", "1") and sum(f.get("WATCHDOG") == "1" for _, f in m) >= 4,
    )
    assert proc.poll() is None, "the gateway exited"
    ready = _first(msgs, "READY", "1")
    print(f"READY=1 after {ready - start:.2f} s")
    pings = [t for t, f in msgs if f.get("WATCHDOG") == "1" and t >= ready]
    assert len(pings) >= 2, msgs
    gaps = [b - a for a, b in zip([ready, *pings], pings, strict=False)]
    assert max(gaps) <= WATCHDOG_S, gaps  # systemd would kill it after WATCHDOG_USEC

    proc.send_signal(signal.SIGHUP)  # ExecReload=/bin/kill -HUP $MAINPID
    msgs = _messages(sock, 5.0, lambda m: _has(m, "RELOADING", "1") and _has(m, "READY", "1"))
    reloading = _first(msgs, "RELOADING", "1")
    assert _first([m for m in msgs if m[0] >= reloading], "READY", "1") >= reloading
    assert proc.poll() is None, "SIGHUP ended the gateway"

    proc.send_signal(signal.SIGTERM)  # systemctl stop
    msgs = _messages(sock, 5.0, lambda m: _has(m, "STOPPING", "1"))
    _first(msgs, "STOPPING", "1")
    assert proc.wait(timeout=15) == 0
