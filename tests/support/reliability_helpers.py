"""Helpers for the reliability tests: scripted and misbehaving PLCs, configs, probes."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pymodbus.client import AsyncModbusTcpClient

from bench._net import wait_port
from gateway.config import Config, parse_config
from gateway.wire.codec import encode_values
from gateway.wire.registers import RegisterServer

FAKE = "gateway_fake_analyze_rel:analyze"


class SilentServer:
    """Accepts TCP connections, reads and discards everything, never answers."""

    def __init__(self) -> None:
        self.port = 0
        self.connections = 0
        self._server: asyncio.Server | None = None
        self._writers: list[asyncio.StreamWriter] = []

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.connections += 1
        self._writers.append(writer)
        with contextlib.suppress(Exception):
            while await reader.read(4096):
                pass

    async def __aenter__(self) -> SilentServer:
        self._server = await asyncio.start_server(self._handle, "127.0.0.1", 0)
        self.port = self._server.sockets[0].getsockname()[1]
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._server is not None
        self._server.close()
        for w in self._writers:
            w.close()
        with contextlib.suppress(Exception):
            await self._server.wait_closed()


class ScriptedPlc:
    """A Modbus server whose holding registers hold float32 values set by the test:
    ``plc.set(address, value, word_order)``; ``size`` registers (reads beyond: exception 2)."""

    def __init__(self, size: int = 64, port: int = 0) -> None:
        self.image = np.zeros(size, dtype=np.uint16)
        self.server = RegisterServer({"holding": self.image, "input": self.image},
                                     host="127.0.0.1", port=port, unit_id=1, capacity=1024)

    @property
    def port(self) -> int:
        return self.server.port

    def set(self, address: int, value: float, word_order: str = "big") -> None:
        self.image[address:address + 2] = encode_values([value], "float32", word_order)[0]

    def resize(self, size: int) -> None:
        """Grow/shrink the served image (a block beyond it answers exception 2)."""
        new = np.zeros(size, dtype=np.uint16)
        n = min(size, len(self.image))
        new[:n] = self.image[:n]
        self.image = new
        self.server.images["holding"] = new
        self.server.images["input"] = new

    async def start(self) -> ScriptedPlc:
        await self.server.start()
        return self

    async def stop(self) -> None:
        await self.server.stop()


async def feed(plc: ScriptedPlc, period: float, fn: Callable[[int, ScriptedPlc], None]) -> None:
    """Call ``fn(k, plc)`` every ``period`` seconds (a task; cancel to stop)."""
    k = 0
    while True:
        fn(k, plc)
        k += 1
        await asyncio.sleep(period)


def device(name: str, port: int, *, poll: float = 0.1, timeout: float = 0.3,
           **extra: Any) -> dict[str, Any]:
    return {"name": name, "protocol": "modbus", "host": "127.0.0.1", "port": port,
            "unit_id": 1, "poll_interval_s": poll, "timeout_s": timeout,
            "max_registers_per_request": 125, **extra}


def loop(name: str, dev: str, address: int, result_address: int, *, window_s: float = 10.0,
         **extra: Any) -> dict[str, Any]:
    return {"name": name, "device": dev, "op": {"address": address, "type": "float32"},
            "pv": {"address": address + 2, "type": "float32"}, "window_s": window_s,
            "result_address": result_address, **extra}


def config(devices: list[dict[str, Any]], loops: list[dict[str, Any]], **gateway: Any
           ) -> Config:
    raw = {"gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                       "reconnect_max_s": 0.5, **gateway},
           "metrics": {"listen": "127.0.0.1:0"},
           "modbus_server": {"listen": "127.0.0.1:0", "unit_id": 1},
           "devices": devices, "loops": loops}
    return parse_config(raw, "<reliability test>")


def raw_config(devices: list[dict[str, Any]], loops: list[dict[str, Any]], **gateway: Any
               ) -> dict[str, Any]:
    return {"gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                        "reconnect_max_s": 0.5, **gateway},
            "metrics": {"listen": "127.0.0.1:0"},
            "modbus_server": {"listen": "127.0.0.1:0", "unit_id": 1},
            "devices": devices, "loops": loops}


async def read_codes(port: int, addresses: dict[str, int]) -> dict[str, int | None]:
    """Verdict code (register +0) of each loop's block in the result server; None if the
    read was refused (no such block)."""
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
    await client.connect()
    try:
        out: dict[str, int | None] = {}
        for name, addr in addresses.items():
            rsp = await client.read_holding_registers(addr, count=1, device_id=1)
            out[name] = None if rsp.isError() else int(rsp.registers[0])
        return out
    finally:
        client.close()


def scrape(port: int) -> str:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=5) as rsp:
        return str(rsp.read().decode())


def lateness(starts: list[float], period: float) -> tuple[np.ndarray, np.ndarray]:
    """``(late, missed)``: how late each tick started against the absolute schedule
    ``t0 + k * period`` (s, less the smallest offset: the schedule's own phase), and how
    many ticks were missed just before it.

    The ticks are laid on the schedule one after the other: each takes the slot after the
    previous tick's, or a later one where the time between two starts leaves slots empty
    (each a missed tick). A tick that starts more than half a period late therefore reads
    as a missed tick and a tick early, and every tick after it a period late: with the
    poller's own count of missed ticks (none, or ``missed.sum()``) and a bound under the
    period, a late tick always fails a test (a tick taken for the nearest slot, as before
    issue 31, read up to half a period late as early)."""
    t = np.asarray(starts, dtype=np.float64)
    steps = np.maximum(1, np.round(np.diff(t) / period)).astype(np.int64)
    slot = np.concatenate(([0], np.cumsum(steps)))
    d = t - (t[0] + slot * period)
    return d - d.min(), np.concatenate(([0], steps - 1))


async def until(pred: Callable[[], bool], limit_s: float = 20.0, step: float = 0.02) -> None:
    """Wait until ``pred()`` holds (polling: the conditions are plain attributes)."""
    async with asyncio.timeout(limit_s):
        while not pred():  # noqa: ASYNC110 - nothing to wait on but a counter
            await asyncio.sleep(step)


# ---------------------------------------------------------------------- subprocesses

PYTHON = sys.executable


def start_plc_sim(tmp: Path, port: int, loops: int = 2, ts: float = 0.1,
                  time_scale: float = 1.0) -> subprocess.Popen[bytes]:
    """``stiction-gateway plc-sim`` as a subprocess with ``loops`` healthy loops (OP of
    loop k at 4k, PV at 4k + 2)."""
    cfg = tmp / f"plc-sim-{port}.yaml"
    cfg.write_text(yaml.safe_dump({
        "listen": f"127.0.0.1:{port}", "ts": ts, "time_scale": time_scale,
        "loops": [{"name": f"L{k}", "scenario": "table4-case2" if k % 2 else "healthy",
                   "noise": 0.05} for k in range(loops)]}))
    proc = subprocess.Popen([PYTHON, "-m", "gateway.cli", "plc-sim", "--config", str(cfg)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_port(port)
    return proc


def sim_loops(n: int, device_name: str = "plc", *, window_s: float = 10.0
              ) -> list[dict[str, Any]]:
    return [loop(f"L{k}", device_name, 4 * k, 20 * k, window_s=window_s) for k in range(n)]


def children(pid: int) -> list[int]:
    """The process ids of ``pid``'s children (Linux /proc; empty if it has none)."""
    with contextlib.suppress(OSError):
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
        return [int(c) for c in text.split()]
    return []


def sigkill(proc: subprocess.Popen[bytes]) -> None:
    """SIGKILL a gateway and then its analysis workers (SIGKILL orphans them: systemd's
    KillMode=mixed would end them, here the test does)."""
    workers = children(proc.pid)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    for pid in workers:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def start_gateway(cfg: Path, log: Path, env: dict[str, str] | None = None
                  ) -> subprocess.Popen[bytes]:
    with open(log, "ab") as f:
        return subprocess.Popen([PYTHON, "-m", "gateway.cli", "run", "--config", str(cfg)],
                                stdout=f, stderr=subprocess.STDOUT,
                                env={**os.environ, **(env or {})})


def stop(proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM, limit_s: float = 15.0
         ) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.wait(limit_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait(5)


def wait_log(log: Path, text: str, limit_s: float = 90.0) -> str:
    """Wait for ``text`` in ``log``; the default bounds a gateway's start on a loaded box (its
    imports took over 30 s with the suite's four workers and another run on two cores)."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        content = log.read_text(errors="replace") if log.exists() else ""
        if text in content:
            return content
        time.sleep(0.05)
    raise TimeoutError(f"{text!r} not in {log}:\n{content}")


# ---------------------------------------------------------------------- the box itself

class HeldWatch:
    """Whether the machine ran this process: while the watch is on, a thread wakes every
    2 ms and notes each wake more than ``limit_s`` late during which the whole process used
    under half the wall time in CPU (``time.process_time``, every thread): the operating
    system held the process (other processes had the cores). A late wake with the process
    busy in CPU is the process's own doing (an event loop blocked by its own work) and is
    not noted, so a timing test may retry a run the box held, never one the code delayed.

    ``held`` lists ``(monotonic start, seconds)`` of each episode."""

    def __init__(self, limit_s: float = 0.015) -> None:
        self.limit_s = limit_s
        self.held: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="held-watch", daemon=True)

    def _watch(self) -> None:
        wall, cpu = time.monotonic(), time.process_time()
        while not self._stop.wait(0.002):
            w, c = time.monotonic(), time.process_time()
            if w - wall > self.limit_s and c - cpu < 0.5 * (w - wall):
                self.held.append((wall, w - wall))
            wall, cpu = w, c

    def __enter__(self) -> HeldWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)

    def __str__(self) -> str:
        worst = max((s for _, s in self.held), default=0.0)
        return f"process held by the machine {len(self.held)} times (longest {worst * 1e3:.0f} ms)"
