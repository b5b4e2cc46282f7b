"""A wall clock stepped back across restarts (issue 31, finding 1), as real processes: the
scenario ``tests/e2e/test_clock_step.py`` checks on this tree and ``python -m bench
hostile`` runs on the baseline and this tree side by side (bench/attacks/_clock_windows_storm.py).

``stiction-gateway run`` of a tree polls a memory device every 0.1 s, analyses every 0.4 s
and writes its state every 2 s. Run 1 is on time and stops cleanly; 1 s later run 2 starts
with its wall clock an hour back (libfaketime preloaded: the process and its analysis
workers see the clock an hour behind, the monotonic clock untouched). SCADA reads the loop's
sequence number while run 2 runs; run 2 is SIGKILLed just before its next state write (the
file lags what SCADA read by most of a persist interval); run 3 starts with the clock two
hours back. :func:`clock_case` returns what a plant engineer would see: the windows' runs of
quality after each restart, the sequence numbers read, run 2's journal and its
``stiction_state_clock_back_seconds``.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import socket
import struct
import subprocess
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench._net import free_port, wait_port
from bench.attacks._arena import start_gateway, stop_gateway, wait_ready
from bench.attacks._attacks import read_frame

POLL_S = 0.1
PERSIST_S = 2.0
ANALYSIS_S = 0.4
DOWN_S = 1.0  # run 1 -> run 2

__all__ = ["ANALYSIS_S", "PERSIST_S", "clock_case", "faketime"]


def faketime(back_s: float) -> dict[str, str] | None:
    """The environment of a process whose wall clock is ``back_s`` seconds behind (Debian's
    libfaketime), or None where it is not installed."""
    libs = sorted(Path("/usr/lib").glob("*/faketime/libfaketime.so.1"))
    if not libs:
        return None
    return {"LD_PRELOAD": str(libs[0]), "FAKETIME": f"-{back_s:.0f}",
            "FAKETIME_DONT_FAKE_MONOTONIC": "1"}


def _config(path: Path, state: Path) -> dict[str, int]:
    ports = {"metrics": free_port(), "modbus": free_port()}
    rows = [[round(50.0 + 10.0 * math.sin(k / 5.0), 4), round(20.0 + math.cos(k / 7.0), 4)]
            for k in range(400)]
    path.write_text(yaml.safe_dump({
        "gateway": {"analysis_interval_s": ANALYSIS_S, "analysis_workers": 1,
                    "state_file": str(state), "persist_interval_s": PERSIST_S},
        "metrics": {"listen": f"127.0.0.1:{ports['metrics']}"},
        "modbus_server": {"listen": f"127.0.0.1:{ports['modbus']}", "unit_id": 1},
        "plant": {"enabled": False},
        "devices": [{"name": "plc", "protocol": "memory", "poll_interval_s": POLL_S,
                     "timeout_s": 1.0, "repeat": True, "values": rows}],
        "loops": [{"name": "L0", "device": "plc", "op": {"column": 0}, "pv": {"column": 1},
                   "window_s": 60.0, "result_address": 0}]}))
    return ports


def seq(port: int, tries: int = 6) -> int:
    """The loop's sequence number (register 1 of its result block), as SCADA reads it
    (again after a read that gets no answer within 10 s: a box loaded by other work)."""
    for attempt in range(tries):
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
                s.sendall(read_frame(1, 0, 2))
                reply = b""
                while len(reply) < 13:
                    chunk = s.recv(64)
                    if not chunk:
                        raise ConnectionError("closed")
                    reply += chunk
            return int(struct.unpack(">HH", reply[9:13])[1])
        except OSError:
            if attempt == tries - 1:
                raise
    raise AssertionError("unreachable")


def runs(q: np.ndarray) -> list[tuple[str, int]]:
    """A window's qualities as runs: [("GOOD", 39), ("MISSING", 4), ...]."""
    from gateway.core.points import Quality  # noqa: PLC0415 - this tree's

    out: list[tuple[str, int]] = []
    for x in q.tolist():
        name = Quality(x).name
        if out and out[-1][0] == name:
            out[-1] = (name, out[-1][1] + 1)
        else:
            out.append((name, 1))
    return out


def window(state: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(op, pv, quality) of the loop's window in the state file."""
    from gateway.outputs.statefile import read_state  # noqa: PLC0415 - this tree's reader

    _header, arrays = read_state(state)
    return arrays["b0_op"][:, 0], arrays["b0_pv"][:, 0], arrays["b0_q"][:, 0]


def _metric(port: int, name: str) -> float | None:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=60) as rsp:
        for line in rsp.read().decode().splitlines():
            if line.startswith(name + " "):
                return float(line.split()[-1])
    return None


def _kill(proc: subprocess.Popen[bytes]) -> None:
    """SIGKILL the gateway and its analysis workers (systemd's KillMode=mixed would)."""
    workers: list[int] = []
    with contextlib.suppress(OSError):
        text = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text()
        workers = [int(c) for c in text.split()]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    for pid in workers:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def clock_case(tree: Path, work: Path, env2: dict[str, str], env3: dict[str, str]
               ) -> dict[str, Any]:
    """The scenario of the module with the gateway of ``tree``; ``env2``/``env3``: run 2's
    and run 3's clocks (:func:`faketime`). Raises RuntimeError if a run does not start."""
    work.mkdir(parents=True, exist_ok=True)
    state, cfg = work / "gw.state", work / "gw.yaml"
    logs = [work / f"gw{k}.log" for k in (1, 2, 3)]
    ports = _config(cfg, state)
    out: dict[str, Any] = {}

    def start(k: int, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        proc = start_gateway(tree, cfg, logs[k - 1], env)
        if not wait_ready(proc, logs[k - 1], 120.0):
            stop_gateway(proc)
            raise RuntimeError(f"run {k} did not start: {logs[k - 1].read_text()[-800:]}")
        wait_port(ports["modbus"])
        return proc

    gw = start(1)  # on time: a few seconds of samples, a clean stop
    try:
        deadline = time.monotonic() + 30
        while seq(ports["modbus"]) < 3 and time.monotonic() < deadline:
            time.sleep(0.1)
        out["seq1"] = seq(ports["modbus"])
    finally:
        out["exit1"] = stop_gateway(gw)
    out["runs1"] = runs(window(state)[2])
    time.sleep(DOWN_S)

    gw = start(2, env2)  # the clock an hour back
    try:
        out["clock_back"] = _metric(ports["metrics"], "stiction_state_clock_back_seconds")
        seen = [seq(ports["modbus"])]
        written = state.stat().st_mtime
        while state.stat().st_mtime == written:  # SCADA reads on; kill just before the
            seen.append(seq(ports["modbus"]))  # next write, so that the file lags
            time.sleep(0.05)
        time.sleep(PERSIST_S - 0.4)
        seen.append(seq(ports["modbus"]))
        out["runs2"] = runs(window(state)[2])
    finally:
        _kill(gw)
    out["seq2"] = seen
    out["log2"] = logs[1].read_text(errors="replace")

    gw = start(3, env3)  # after the kill, the clock two hours back
    try:
        after = [seq(ports["modbus"])]
        for _ in range(10):
            time.sleep(ANALYSIS_S / 2)
            after.append(seq(ports["modbus"]))
    finally:
        out["exit3"] = stop_gateway(gw)
    out["seq3"] = after
    op, pv, q = window(state)
    out["runs3"] = runs(q)
    from gateway.core.windows import analysis_segment  # noqa: PLC0415

    out["segment"] = len(analysis_segment(op, pv, q)[0])
    return out


def summary(out: dict[str, Any], unknown_rows: int) -> dict[str, Any]:
    """What the scenario shows: the gap after each restart (MISSING rows after the samples
    before it; 0: joined), whether SCADA read a lower sequence number after the kill, and
    whether the analysis saw only samples since the last restart."""

    def gap_after(rs: list[tuple[str, int]], k: int) -> int:
        """MISSING rows in the k-th run of MISSING (0 if there is none)."""
        missing = [n for name, n in rs if name == "MISSING"]
        return missing[k] if len(missing) > k else 0

    gaps = [gap_after(out["runs2"], 0), gap_after(out["runs3"], 1)]
    missing = [k for k, (name, _n) in enumerate(out["runs3"]) if name == "MISSING"]
    since = sum(n for _name, n in out["runs3"][missing[-1] + 1:]) if missing else 0
    seq2, seq3 = out["seq2"], out["seq3"]
    return {"gap_clean": gaps[0], "gap_kill": gaps[1],
            "joined": any(g < unknown_rows for g in gaps),
            "seq_last_before_kill": seq2[-1], "seq_first_after": seq3[0],
            "seq_back": seq3[0] <= seq2[-1] or seq3 != sorted(seq3) or seq2 != sorted(seq2)
            or seq2[0] < out["seq1"],
            "segment": out["segment"], "since_restart": since,
            "warned": "behind the file's last write" in out["log2"],
            "clock_back": out["clock_back"]}
