"""Issue 6 item 6: systemd integration, checked by playing systemd's side of sd_notify.

* ``stiction-gateway run`` as a subprocess with a real datagram socket as ``$NOTIFY_SOCKET``
  and ``$WATCHDOG_USEC``: READY=1 once polling runs, WATCHDOG=1 at half the watchdog
  interval, RELOADING=1 (+ MONOTONIC_USEC) then READY=1 on SIGHUP with the new config in
  force, STOPPING=1 on SIGTERM and exit 0 within ``SHUTDOWN_BOUND_S`` with the state file
  flushed.

(The watchdog withheld while a poller stalls: tests/runtime/test_watchdog.py, in memory.)
"""

from __future__ import annotations

import signal
import socket
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from reliability_helpers import (
    device,
    raw_config,
    scrape,
    sim_loops,
    start_gateway,
    start_plc_sim,
    stop,
)

from bench._net import free_port
from gateway.outputs.statefile.format import read_state

SHUTDOWN_BOUND_S = 5.0
WATCHDOG_USEC = 400_000  # pings every 0.2 s


class NotifySocket:
    def __init__(self, path: Path) -> None:
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.messages: list[tuple[float, str]] = []

    def expect(self, prefix: str, limit_s: float = 30.0) -> tuple[float, str]:
        """Receive until a message starting with ``prefix``; keeps every message."""
        deadline = time.monotonic() + limit_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {prefix!r}; got {self.messages}")
            self.sock.settimeout(left)
            msg = self.sock.recv(4096).decode()
            self.messages.append((time.monotonic(), msg))
            if msg.startswith(prefix):
                return self.messages[-1]

    def drain(self, seconds: float) -> list[tuple[float, str]]:
        got: list[tuple[float, str]] = []
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                got.append((time.monotonic(), self.sock.recv(4096).decode()))
            except TimeoutError:
                break
        self.messages.extend(got)
        return got

    def close(self) -> None:
        self.sock.close()


@pytest.mark.timing
@pytest.mark.timeout(120)
def test_notify_protocol_reload_and_clean_shutdown(tmp_path: Path) -> None:
    port, metrics_port = free_port(), free_port()
    plc = start_plc_sim(tmp_path, port, loops=3, ts=0.1)
    state = tmp_path / "gw.state"
    cfg = tmp_path / "gw.yaml"
    raw = raw_config([device("plc", port, poll=0.1)], sim_loops(2),
                     state_file=str(state), persist_interval_s=3600)
    raw["metrics"]["listen"] = f"127.0.0.1:{metrics_port}"
    cfg.write_text(yaml.safe_dump(raw))
    log = tmp_path / "gw.log"
    ns = NotifySocket(tmp_path / "notify.sock")
    gw = start_gateway(cfg, log, env={"NOTIFY_SOCKET": str(ns.path),
                                      "WATCHDOG_USEC": str(WATCHDOG_USEC)})
    try:
        _, ready = ns.expect("READY=1")
        assert "STATUS=polling 1 devices (1 up), 2 loops" in ready
        pings = [m for m in ns.drain(1.0) if m[1] == "WATCHDOG=1"]
        assert len(pings) >= 3
        gaps = np.diff([t for t, _ in pings])
        assert gaps.max() < 0.4  # about WATCHDOG_USEC / 2

        # SIGHUP with a loop added: RELOADING=1, MONOTONIC_USEC, then READY=1
        raw["loops"] = sim_loops(3)
        cfg.write_text(yaml.safe_dump(raw))
        gw.send_signal(signal.SIGHUP)
        _, reloading = ns.expect("RELOADING=1")
        assert reloading.split("\n")[1].startswith("MONOTONIC_USEC=")
        assert int(reloading.split("=")[-1]) > 0
        _, ready2 = ns.expect("READY=1")
        assert "3 loops" in ready2
        assert 'stiction_loop_verdict{loop="L2"' in scrape(metrics_port)

        # SIGTERM: STOPPING=1, exit 0 within the bound, state flushed at exit
        t_term = time.monotonic()
        wall_term = time.time()
        gw.send_signal(signal.SIGTERM)
        ns.expect("STOPPING=1", limit_s=SHUTDOWN_BOUND_S)
        code = gw.wait(SHUTDOWN_BOUND_S + 5)
        shutdown_s = time.monotonic() - t_term
    finally:
        stop(gw)
        stop(plc)
        ns.close()
    text = log.read_text()
    print(f"\nshutdown after SIGTERM: {shutdown_s:.2f} s (bound {SHUTDOWN_BOUND_S} s)")
    assert code == 0, text
    assert shutdown_s < SHUTDOWN_BOUND_S
    assert "gateway stopped" in text and "Traceback" not in text
    assert state.stat().st_mtime >= wall_term - 0.01  # written by the shutdown
    header, arrays = read_state(state)
    assert [e["name"] for e in header["banks"][0]["loops"]] == ["L0", "L1", "L2"]
    assert len(arrays["b0_t"]) >= 10
    kinds = [m.split("=")[0] for _, m in ns.messages]
    assert kinds.index("READY") < kinds.index("RELOADING") < kinds.index("STOPPING")
