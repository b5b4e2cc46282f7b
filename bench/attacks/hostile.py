"""Red-team benchmarks: issue 15 (here), issue 22 (bench/attacks/_server_attacks.py) and
issue 31 (bench/attacks/_clock_windows_storm.py: a wall clock stepped back, short windows, a
reconnect storm), in turn.

Issue 15: the gateway under 2,000 half-open connections and 2,000 garbage frames, with the
open-files limit of the systemd unit.

``python -m bench hostile`` runs all three; ``BENCH_HOSTILE=31`` (or ``22``, ``15``) one.

Issue 15's processes: a simulated PLC (20 loops over Modbus, Ts 0.5 s),
the gateway (``stiction-gateway run``, ``RLIMIT_NOFILE`` = the unit's ``LimitNOFILE``, state
written every 2 s), an honest SCADA client in this process (one connection, 20 registers
every 50 ms) and the attacker in its own process. Three phases of 12 s: *before*, *during*
(the attacker keeps 1,000 half-open connections to each server, reopening each one the
gateway closes, and sends 1,000 garbage frames to each: Modbus frames with a wrong protocol
id, length or no end, HTTP with a bad request line, a body, 9 KiB of headers; the PLC is
restarted in the middle), *after*. Per phase: the connections the gateway holds (its
``stiction_server_connections``) and its open files, the attacker's connections open on
its side, honest reads and their latency (p99, max), a /metrics scrape, state-file writes,
the gateway's RSS and its log growth.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing
import os
import random
import resource
import signal
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench._net import free_port, wait_port
from bench.attacks._attacks import Scada

UNIT = Path(__file__).resolve().parents[2] / "deploy" / "systemd" / "stiction-gateway.service"
PHASE_S = 12.0
HALF_OPEN = 1000  # per server: 2,000 in all
GARBAGE = 1000  # per server: 2,000 in all
LOOPS = 20


def unit_nofile() -> int:
    for line in UNIT.read_text().splitlines():
        if line.startswith("LimitNOFILE="):
            return int(line.split("=", 1)[1])
    return 1024  # systemd's default soft limit


# ------------------------------------------------------------------------ the attacker


def _garbage_modbus(k: int) -> bytes:
    kind = k % 4
    if kind == 0:  # protocol id 7
        return struct.pack(">HHHB", k, 7, 6, 1) + bytes([3, 0, 0, 0, 1])
    if kind == 1:  # length 0
        return struct.pack(">HHHB", k, 0, 0, 1)
    if kind == 2:  # a header announcing more than any frame holds
        return struct.pack(">HHHB", k, 0, 4000, 1) + os.urandom(200)
    return os.urandom(random.randint(1, 300))


def _garbage_http(k: int) -> bytes:
    kind = k % 4
    if kind == 0:
        return b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + os.urandom(64)  # TLS hello
    if kind == 1:
        return b"POST /metrics HTTP/1.1\r\nContent-Length: 5\r\n\r\nhello"
    if kind == 2:
        return b"GET /metrics HTTP/1.1\r\n" + b"X-Fill: " + b"a" * 9000 + b"\r\n\r\n"
    return b"GARBAGE\r\n\r\n"


async def _attacker(host: str, ports: tuple[int, int], stop: asyncio.Event,
                    stats: dict[str, int]) -> None:
    async def hold(port: int) -> None:
        while not stop.is_set():
            try:
                reader, writer = await asyncio.open_connection(host, port)
            except OSError:
                stats["refused"] += 1
                await asyncio.sleep(0.05)
                continue
            stats["open"] += 1
            try:
                read = asyncio.ensure_future(reader.read(1))
                halt = asyncio.ensure_future(stop.wait())
                await asyncio.wait({read, halt}, return_when=asyncio.FIRST_COMPLETED)
                halt.cancel()
                if read.done():
                    stats["closed_by_gateway"] += 1
                else:
                    read.cancel()
            except OSError:
                stats["closed_by_gateway"] += 1
            finally:
                stats["open"] -= 1
                writer.close()
            await asyncio.sleep(0.05)

    async def garbage(port: int, make: Any, frames: range) -> None:
        for k in frames:
            if stop.is_set():
                return
            with contextlib.suppress(OSError):
                reader, writer = await asyncio.open_connection(host, port)
                writer.write(make(k))
                stats["garbage"] += 1
                with contextlib.suppress(OSError, TimeoutError):
                    await writer.drain()
                    await asyncio.wait_for(reader.read(65536), 0.5)
                writer.close()

    tasks = [asyncio.create_task(hold(p)) for p in ports for _ in range(HALF_OPEN)]
    senders = 50  # per server, each sending its share of the frames
    tasks += [asyncio.create_task(garbage(port, make, range(w, GARBAGE, senders)))
              for port, make in ((ports[0], _garbage_modbus), (ports[1], _garbage_http))
              for w in range(senders)]
    await stop.wait()
    await asyncio.gather(*tasks, return_exceptions=True)


def _attack_process(host: str, ports: tuple[int, int], conn: Any) -> None:
    _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))

    async def main() -> None:
        stop = asyncio.Event()
        stats = dict.fromkeys(("open", "refused", "closed_by_gateway", "garbage"), 0)
        task = asyncio.create_task(_attacker(host, ports, stop, stats))
        loop = asyncio.get_running_loop()
        while True:
            msg = await loop.run_in_executor(None, conn.recv)
            if msg == "stop":
                break
            conn.send(dict(stats))
        stop.set()
        await task
        conn.send(dict(stats))

    asyncio.run(main())


# ------------------------------------------------------------------------ the honest side


def _scrape(port: int) -> tuple[float, str]:
    t0 = time.perf_counter()
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10) as rsp:
            text = rsp.read().decode()
    except OSError as exc:
        return float("nan"), f"error: {exc}"
    return time.perf_counter() - t0, text


def _sample(text: str, series: str) -> float:
    for line in text.splitlines():
        if line.startswith(series + " "):
            return float(line.split()[-1])
    return float("nan")


def _rss_mib(pid: int) -> float:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _fds(pid: int) -> int:
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return -1


# ------------------------------------------------------------------------ the run


def _configs(tmp: Path, plc_port: int, metrics_port: int, result_port: int) -> Path:
    (tmp / "plc.yaml").write_text(yaml.safe_dump({
        "listen": f"127.0.0.1:{plc_port}", "ts": 0.5,
        "loops": [{"name": f"L{k}", "scenario": "healthy", "noise": 0.05}
                  for k in range(LOOPS)]}))
    cfg = tmp / "gw.yaml"
    cfg.write_text(yaml.safe_dump({
        "gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1, "reconnect_max_s": 1.0,
                    "state_file": str(tmp / "gw.state"), "persist_interval_s": 2.0},
        "metrics": {"listen": f"127.0.0.1:{metrics_port}"},
        "modbus_server": {"listen": f"127.0.0.1:{result_port}", "unit_id": 1},
        "devices": [{"name": "plc", "protocol": "modbus", "host": "127.0.0.1",
                     "port": plc_port, "unit_id": 1, "poll_interval_s": 0.5, "timeout_s": 0.5,
                     "max_registers_per_request": 125}],
        "loops": [{"name": f"L{k}", "device": "plc",
                   "op": {"address": 4 * k, "type": "float32"},
                   "pv": {"address": 4 * k + 2, "type": "float32"},
                   "window_s": 60.0, "result_address": 20 * k} for k in range(LOOPS)]}))
    return cfg


def _plc(tmp: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "gateway.cli", "plc-sim", "--config",
                             str(tmp / "plc.yaml")], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _phase(name: str, gw: subprocess.Popen[bytes], honest: Scada, *, ports: dict[str, int],
           state: Path, log: Path, attacker: Any = None, during: Any = None) -> dict[str, Any]:
    lat0 = len(honest.latency)
    log0 = log.stat().st_size
    writes, last = 0, state.stat().st_mtime_ns if state.exists() else 0
    t_end = time.monotonic() + PHASE_S
    half = time.monotonic() + PHASE_S / 2
    fds, extra = [], None
    while time.monotonic() < t_end:
        time.sleep(0.25)
        fds.append(_fds(gw.pid))
        with contextlib.suppress(OSError):
            m = state.stat().st_mtime_ns
            writes, last = writes + (m != last), m
        if during is not None and time.monotonic() >= half:
            extra, during = during(), None
    scrape_s, text = _scrape(ports["metrics"])
    answers = np.array(honest.latency[lat0:]) * 1e3
    lat = answers[np.isfinite(answers)]
    row = {"phase": name, "modbus": _sample(text, 'stiction_server_connections{server="modbus"}'),
           "metrics": _sample(text, 'stiction_server_connections{server="metrics"}'),
           "fds": max(fds), "reads": len(lat), "failed": int(np.isnan(answers).sum()),
           "p99": float(np.percentile(lat, 99)) if len(lat) else float("nan"),
           "max": float(lat.max()) if len(lat) else float("nan"), "scrape": scrape_s,
           "writes": writes, "rss": _rss_mib(gw.pid), "log": log.stat().st_size - log0,
           "text": text, "extra": extra, "held": None}
    if attacker is not None:
        attacker.send("stats")
        row["held"] = attacker.recv()["open"]
    return row


def run() -> list[dict[str, Any]]:
    nofile = unit_nofile()
    plc_port, metrics_port, result_port = free_port(), free_port(), free_port()
    ports = {"metrics": metrics_port, "modbus": result_port}
    with tempfile.TemporaryDirectory(prefix="bench-hostile-") as tmpdir:
        tmp = Path(tmpdir)
        cfg = _configs(tmp, plc_port, metrics_port, result_port)
        plc = _plc(tmp)
        wait_port(plc_port)
        log = tmp / "gw.log"

        def limit() -> None:
            resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))

        with open(log, "wb") as out:
            gw = subprocess.Popen([sys.executable, "-m", "gateway.cli", "run", "--config",
                                   str(cfg)], stdout=out, stderr=subprocess.STDOUT,
                                  preexec_fn=limit)  # noqa: PLW1509 - no other thread yet
        honest = Scada(result_port, period_s=0.05, timeout_s=5.0)
        rows: list[dict[str, Any]] = []
        ctx = multiprocessing.get_context("spawn")
        conn, child = ctx.Pipe()
        attacker = ctx.Process(target=_attack_process,
                               args=("127.0.0.1", (result_port, metrics_port), child))
        try:
            wait_port(result_port)
            wait_port(metrics_port)
            honest.start()
            time.sleep(2.0)
            rows.append(_phase("before", gw, honest, ports=ports, state=tmp / "gw.state",
                               log=log))
            attacker.start()
            time.sleep(2.0)  # the attack builds up
            restart: dict[str, float] = {}

            def restart_plc() -> float:
                nonlocal plc
                plc.kill()
                plc.wait()
                plc = _plc(tmp)
                t0 = time.monotonic()
                wait_port(plc_port)
                up = float("nan")
                while time.monotonic() - t0 < 8:
                    _s, text = _scrape(metrics_port)
                    polls = _sample(text, 'stiction_device_up{device="plc"}')
                    if polls == 1.0:
                        up = time.monotonic() - t0
                        break
                    time.sleep(0.1)
                restart["up_s"] = up
                return up

            rows.append(_phase("during", gw, honest, ports=ports, state=tmp / "gw.state",
                               log=log, attacker=conn, during=restart_plc))
            conn.send("stop")
            attack = conn.recv()
            attacker.join(30)
            time.sleep(1.0)
            rows.append(_phase("after", gw, honest, ports=ports, state=tmp / "gw.state",
                               log=log))
            rows[1]["attack"] = attack
        finally:
            honest.stop.set()
            if attacker.is_alive():
                attacker.kill()
            gw.send_signal(signal.SIGTERM)
            try:
                gw.wait(30)
            except subprocess.TimeoutExpired:
                gw.kill()
            plc.kill()
            plc.wait()
        rows[0]["nofile"] = nofile
        rows[0]["exit"] = gw.returncode
        rows[0]["log_text"] = log.read_text(errors="replace")
    return rows


def main() -> None:
    only = os.environ.get("BENCH_HOSTILE")
    if only in (None, "15"):
        main15()
    if only in (None, "22"):
        from bench import _hostile22  # noqa: PLC0415

        _hostile22.main()
    if only in (None, "31"):
        from bench import _hostile31  # noqa: PLC0415

        _hostile31.main()


def main15() -> None:
    rows = run()
    nofile = rows[0]["nofile"]
    print(f"== hostile: {2 * HALF_OPEN:,} half-open connections and {2 * GARBAGE:,} garbage "
          f"frames (half each to the Modbus result server and /metrics); gateway with "
          f"LimitNOFILE {nofile} as in the unit, max_connections 64 (Modbus) and 16 "
          f"(metrics); {PHASE_S:.0f} s per phase ==")
    head = (f"{'phase':<7} {'held modbus/metrics':>19} {'gw files':>8} {'attacker open':>13} "
            f"{'honest reads':>12} {'failed':>6} {'p99 ms':>7} {'max ms':>7} "
            f"{'/metrics s':>10} {'state writes':>12} {'RSS MiB':>7} {'log bytes':>9}")
    print(head)
    for r in rows:
        held = "-" if r["held"] is None else f"{r['held']:,}"
        print(f"{r['phase']:<7} {r['modbus']:>9.0f} / {r['metrics']:<7.0f} {r['fds']:>8} "
              f"{held:>13} {r['reads']:>12} {r['failed']:>6} {r['p99']:>7.1f} {r['max']:>7.1f} "
              f"{r['scrape']:>10.3f} {r['writes']:>12} {r['rss']:>7.1f} {r['log']:>9}")
    during = rows[1]
    attack = during["attack"]
    text = rows[2]["text"]
    closed = {f"{s}/{r}": _sample(text, f'stiction_server_connections_closed_total'
                                        f'{{reason="{r}",server="{s}"}}')
              for s in ("modbus", "metrics") for r in ("limit", "idle", "protocol")}
    print(f"attacker: {attack['closed_by_gateway']:,} of its connections closed by the "
          f"gateway, {attack['garbage']:,} garbage frames sent, {attack['refused']:,} "
          f"connects refused")
    print("closed by the gateway (reason): " + ", ".join(f"{k} {v:,.0f}"
                                                       for k, v in closed.items()))
    print(f"PLC killed and restarted in the middle of the attack: device up again "
          f"{during['extra']:.1f} s after it listened")
    ok = {"honest reads within 1 s p99 during the attack": during["p99"] < 1000,
          "/metrics answered during the attack": during["scrape"] == during["scrape"],
          "state writes during the attack": during["writes"] > 0,
          "the gateway held at most 64 + 16 connections": during["modbus"] <= 64
          and during["metrics"] <= 16,
          "the gateway exited 0 after SIGTERM": rows[0]["exit"] == 0,
          "no 'Too many open files' in its log": "Too many open files" not in rows[0]["log_text"]}
    for what, good in ok.items():
        print(f"  {'yes' if good else 'NO '}  {what}")
    print()


if __name__ == "__main__":
    main()
