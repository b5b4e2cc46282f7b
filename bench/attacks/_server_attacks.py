"""Issue 22 in ``python -m bench hostile``: each attack of the red team against the gateway
of the baseline commit and against this tree's, in one run, side by side (bench/attacks/_arena.py
says how: ``git archive`` of the baseline, two ``stiction-gateway run`` processes, one
after the other, polling the same simulated PLC).

Tables:

1. the attacks on the servers at 2,000 loops polled every second (bench/attacks/_attacks.py): per
   variant the poll rate (GOOD rows of the window per second; nominal 1.0) and the gap rows
   during the attack, RSS growth, the SCADA poller's answers (1 Hz, 20 registers) and p99,
   the slowest honest scrape, the log's growth;
2. crafted state files: does the gateway start, does /metrics answer, the peak RSS, was the
   file set aside;
3. failed state writes (the state folder replaced by a file): are they in the metrics;
4. the smaller findings: a PLC answering function code 4 for 3, a byte count beyond the
   frame, register garbage with no ``range``; a request behind a 404, a request line ending
   in a bare LF;
5. the load the result server serves honestly at 2,000 loops while polling holds
   (clients x reads per second, this tree only).

``BENCH_BASELINE`` names the baseline commit (default: main when the issue was filed).
``BENCH_HOSTILE_ATTACKS`` (comma-separated) limits table 1.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing
import os
import random
import socket
import struct
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench._net import free_port, wait_port
from bench.attacks._arena import (
    LOOPS,
    REPO,
    baseline_tree,
    plc_config,
    rss_mib,
    run_variant,
    start_gateway,
    start_plc,
    stop_gateway,
    wait_ready,
)
from bench.attacks._attacks import ATTACKS, read_frame, rewrite_state, scrape


def _sample(text: str, series: str) -> float | None:
    for line in text.splitlines():
        if line.startswith(series + " "):
            return float(line.split()[-1])
    return None


def _metrics(port: int) -> str:
    import urllib.request  # noqa: PLC0415

    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10) as r:
            return str(r.read().decode())
    except OSError:
        return ""


# ------------------------------------------------------------------ 1. the servers


def attack_table(trees: dict[str, Path], work: Path, plc_port: int) -> list[dict[str, Any]]:
    wanted = os.environ.get("BENCH_HOSTILE_ATTACKS")
    attacks = [a for a in ATTACKS if not wanted or a in wanted.split(",")]
    rows = []
    for attack in attacks:
        for variant, tree in trees.items():
            r = run_variant(tree, work / attack / variant, plc_port, attack)
            r["variant"] = variant
            r.pop("log", None)
            rows.append(r)
            print(f"  ran {attack} {variant}", flush=True)
    return rows


def print_attacks(rows: list[dict[str, Any]]) -> None:
    print(f"{'attack':<17} {'gateway':<7} {'polls':>7} {'of due':>6} {'gaps':>4} "
          f"{'RSS +MiB':>8} {'SCADA':>6} {'p99 ms':>7} {'scrape s':>8} {'scr.ok':>6} "
          f"{'log bytes':>10} {'answers/s':>9}")
    for r in rows:
        if "failed" in r:
            print(f"{r['attack']:<17} {r['variant']:<7} {r['failed'][:80]}")
            continue
        print(f"{r['attack']:<17} {r['variant']:<7} "
              f"{round(r['ratio'] * r['ticks']):>3}/{r['ticks']:<3} {100 * r['ratio']:>5.0f}% "
              f"{r['gaps']:>4} {r['rss_growth']:>8.0f} "
              f"{r['scada_answers']:>3}/{r['scada_asked']:<2} {r['scada_p99_ms']:>7.0f} "
              f"{r['scrape_s']:>8.2f} {r['scrapes_ok']:>2}/{r['scrapes']:<3} "
              f"{r['log_bytes']:>10,} {r['attack_rate']:>9,.0f}")


def attack_checks(rows: list[dict[str, Any]]) -> dict[str, bool]:
    after = [r for r in rows if r["variant"] == "after" and "failed" not in r]
    return {
        "poll rate >= 95 % of nominal under every attack":
            bool(after) and all(r["ratio"] >= 0.95 for r in after),
        "no gap in the windows during any attack": all(r["gaps"] == 0 for r in after),
        "RSS grows less than 200 MiB": all(r["rss_growth"] < 200 for r in after),
        "SCADA at 1 Hz gets at least 19 of 20 answers":
            all(r["scada_answers"] >= min(19, r["scada_asked"] - 1) for r in after),
        "/metrics answers every honest scrape within 2 s":
            all(r["scrapes_ok"] == r["scrapes"] for r in after),
    }


# ------------------------------------------------------------------ 2./3. the state file


def small_config(path: Path, state: Path, *, loops: int = 20, persist_s: float = 0.5
                 ) -> dict[str, int]:
    ports = {"metrics": free_port(), "modbus": free_port()}
    rows = [[50.0 + np.sin(k / 5 + c) for c in range(2 * loops)] for k in range(200)]
    path.write_text(yaml.safe_dump({
        "gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1, "state_file": str(state),
                    "persist_interval_s": persist_s},
        "metrics": {"listen": f"127.0.0.1:{ports['metrics']}"},
        "modbus_server": {"listen": f"127.0.0.1:{ports['modbus']}", "unit_id": 1},
        "devices": [{"name": "plc", "protocol": "memory", "poll_interval_s": 0.1,
                     "timeout_s": 1.0, "repeat": True,
                     "values": [[float(x) for x in r] for r in rows]}],
        "loops": [{"name": f"L{k}", "device": "plc", "op": {"column": 2 * k},
                   "pv": {"column": 2 * k + 1}, "window_s": 60.0, "result_address": 20 * k}
                  for k in range(loops)]}))
    return ports


def good_state_file(config: Path, state: Path) -> None:
    """A state file as this tree writes it for ``config``: windows and an assessment per
    loop (same format version as the baseline's)."""
    from gateway.config import load_config  # noqa: PLC0415
    from gateway.outputs.statefile.format import snapshot, write_state  # noqa: PLC0415
    from gateway.runtime.reload import build_runtime  # noqa: PLC0415
    from stiction import Assessment, Verdict  # noqa: PLC0415

    cfg = load_config(config)
    wall = time.time() - 60
    rt = build_runtime(cfg, wall=wall)
    n = len(cfg.loops)
    for k in range(100):
        for g in rt.groups:
            m = len(g.configs)
            g.bank.append(wall + 0.1 * k, np.full(m, 50.0), np.full(m, 20.0),
                          np.zeros(m, dtype=np.uint8))
    sticky = Assessment(Verdict.STICTION, "bench", oscillating=True, period_s=60.0,
                        stiction_index=0.9, fd=0.02, fs=0.03, jump=0.01, confidence=0.9)
    for i in range(n):
        rt.store.set_result(i, sticky, t=wall, window_fill=1.0, samples=100)
    write_state(state, *snapshot(cfg, rt.groups, rt.store, wall=wall, proc=wall))


def craft(state: Path, case: str) -> None:
    def change(header: dict[str, Any]) -> None:
        first = header["banks"][0]["loops"][0]
        if case == "seq 2**70":
            first["seq"] = 2**70
        elif case == "saved_wall -1e308":
            header["saved_wall"] = -1e308
        elif case == "string in fd":
            first["result"]["assessment"]["fd"] = "0.02"

    rewrite_state(state, change, bomb_bytes=1_600_000_000 if case.startswith("zip") else 0)


STATE_CASES = ("seq 2**70", "saved_wall -1e308", "string in fd", "zip bomb 1.6 GB")


def state_table(trees: dict[str, Path], work: Path) -> list[dict[str, Any]]:
    rows = []
    for case in STATE_CASES:
        for variant, tree in trees.items():
            here = work / "state" / case.replace(" ", "_").replace("*", "") / variant
            here.mkdir(parents=True, exist_ok=True)
            state, log = here / "gw.state", here / "gw.log"
            ports = small_config(here / "gw.yaml", state)
            good_state_file(here / "gw.yaml", state)
            craft(state, case)
            size = state.stat().st_size
            gw = start_gateway(tree, here / "gw.yaml", log)
            peak, status, t0 = 0.0, 0, time.monotonic()
            started = False
            while time.monotonic() - t0 < 60 and gw.poll() is None:
                peak = max(peak, rss_mib(gw.pid, "VmHWM") or 0.0)
                if "gateway running" in log.read_text(errors="replace"):
                    started = True
                    break
                time.sleep(0.02)
            if started:
                time.sleep(1.0)
                _s, status = scrape(ports["metrics"])
                peak = max(peak, rss_mib(gw.pid, "VmHWM") or 0.0)
            code = stop_gateway(gw)
            rows.append({"case": case, "variant": variant, "size": size, "started": started,
                         "exit": code, "status": status, "peak": peak,
                         "aside": bool(list(here.glob("gw.state.corrupt-*")))})
            print(f"  ran state file {case} {variant}", flush=True)
    return rows


def print_state(rows: list[dict[str, Any]]) -> None:
    print(f"{'state file':<18} {'bytes':>10} {'gateway':<7} {'started':>7} {'exit':>4} "
          f"{'/metrics':>8} {'peak RSS MiB':>12} {'set aside':>9}")
    for r in rows:
        print(f"{r['case']:<18} {r['size']:>10,} {r['variant']:<7} "
              f"{'yes' if r['started'] else 'NO':>7} {r['exit']:>4} {r['status'] or '-':>8} "
              f"{r['peak']:>12.0f} {'yes' if r['aside'] else 'no':>9}")


def full_disk(trees: dict[str, Path], work: Path) -> list[dict[str, Any]]:
    rows = []
    for variant, tree in trees.items():
        here = work / "disk" / variant
        folder = here / "state"
        folder.mkdir(parents=True, exist_ok=True)
        log = here / "gw.log"
        ports = small_config(here / "gw.yaml", folder / "gw.state", persist_s=0.3)
        gw = start_gateway(tree, here / "gw.yaml", log)
        try:
            wait_ready(gw, log)
            time.sleep(1.0)
            for f in folder.iterdir():
                f.unlink()
            folder.rmdir()
            folder.write_text("full\n")  # every write fails from now on
            time.sleep(3.0)
            text = _metrics(ports["metrics"])
        finally:
            stop_gateway(gw)
            folder.unlink(missing_ok=True)
        rows.append({"variant": variant,
                     "failures": _sample(text, "stiction_state_write_failures_total"),
                     "errors": log.read_text(errors="replace").count("write failed")})
    return rows


# ------------------------------------------------------------------ 4. smaller


class BadPlc(threading.Thread):
    """Three Modbus servers answering reads wrongly: ``fc`` (function code 4 for 3),
    ``bytecount`` (2 beyond the frame), ``garbage`` (random registers)."""

    MODES = ("fc", "bytecount", "garbage")

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.ports = {m: free_port() for m in self.MODES}
        self.loop = asyncio.new_event_loop()
        self.rng = random.Random(0)

    def run(self) -> None:
        asyncio.set_event_loop(self.loop)
        for mode, port in self.ports.items():
            self.loop.run_until_complete(asyncio.start_server(
                lambda r, w, m=mode: self._serve(m, r, w), "127.0.0.1", port))
        self.loop.run_forever()

    async def _serve(self, mode: str, reader: asyncio.StreamReader,
                     writer: asyncio.StreamWriter) -> None:
        with contextlib.suppress(OSError, asyncio.IncompleteReadError):
            while True:
                tid, _p, length, unit = struct.unpack(">HHHB", await reader.readexactly(7))
                fc, _a, count = struct.unpack(">BHH", await reader.readexactly(length - 1))
                data = bytes(self.rng.getrandbits(8) for _ in range(2 * count))
                if mode == "fc":
                    body = bytes([4, 2 * count]) + data
                elif mode == "bytecount":
                    body = bytes([fc, 2 * count + 2]) + data
                else:
                    body = bytes([fc, 2 * count]) + data
                writer.write(struct.pack(">HHHB", tid, 0, len(body) + 1, unit) + body)

    def stop(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)


def _http(port: int, data: bytes, limit_s: float = 2.0) -> int:
    """How many answers (status lines) came back within ``limit_s``."""
    got = b""
    with socket.create_connection(("127.0.0.1", port), timeout=limit_s) as s:
        s.sendall(data)
        deadline = time.monotonic() + limit_s
        with contextlib.suppress(OSError):
            while time.monotonic() < deadline:
                s.settimeout(max(0.01, deadline - time.monotonic()))
                chunk = s.recv(65536)
                if not chunk:
                    break
                got += chunk
    return got.count(b"HTTP/1.1 ")


def _garbage(state: Path) -> str:
    """What the window of the loop fed register garbage holds: samples kept GOOD, and the
    largest magnitude among them."""
    from gateway.outputs.statefile import read_state  # noqa: PLC0415

    header, arrays = read_state(state)
    for k, bank in enumerate(header["banks"]):
        names = [e["name"] for e in bank["loops"]]
        if "garbage_loop" in names:
            c = names.index("garbage_loop")
            q, pv = arrays[f"b{k}_q"][:, c], arrays[f"b{k}_pv"][:, c]
            good = pv[q == 0]
            biggest = float(np.abs(good).max()) if len(good) else float("nan")
            return (f"{len(good)} of {len(q)} samples GOOD, largest |PV| among them "
                    f"{biggest:.2g}")
    return "no window"


def smaller(trees: dict[str, Path], work: Path) -> list[dict[str, Any]]:
    plc = BadPlc()
    plc.start()
    time.sleep(0.3)
    rows = []
    try:
        for variant, tree in trees.items():
            here = work / "smaller" / variant
            here.mkdir(parents=True, exist_ok=True)
            ports = {"metrics": free_port(), "modbus": free_port()}
            (here / "gw.yaml").write_text(yaml.safe_dump({
                "gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                            "reconnect_max_s": 0.5, "state_file": str(here / "gw.state")},
                "metrics": {"listen": f"127.0.0.1:{ports['metrics']}"},
                "modbus_server": {"listen": f"127.0.0.1:{ports['modbus']}", "unit_id": 1},
                "devices": [{"name": m, "protocol": "modbus", "host": "127.0.0.1",
                             "port": p, "poll_interval_s": 0.2, "timeout_s": 0.5}
                            for m, p in plc.ports.items()],
                "loops": [{"name": f"{m}_loop", "device": m,
                           "op": {"address": 0, "type": "float32"},
                           "pv": {"address": 2, "type": "float32"}, "window_s": 60.0,
                           "result_address": 20 * k}
                          for k, m in enumerate(plc.ports)]}))
            log = here / "gw.log"
            gw = start_gateway(tree, here / "gw.yaml", log)
            try:
                wait_ready(gw, log)
                time.sleep(4.0)
                text = _metrics(ports["metrics"])
                behind = _http(ports["metrics"], b"GET /nope HTTP/1.1\r\n\r\n"
                               b"GET /metrics HTTP/1.1\r\n\r\n")
                bare = _http(ports["metrics"], b"GET /metrics HTTP/1.1\n\n")
            finally:
                stop_gateway(gw)
            logtext = log.read_text(errors="replace")

            def errs(dev: str, kind: str, text: str = text) -> float:
                return _sample(text, f'stiction_poll_errors_total{{device="{dev}",'
                                     f'kind="{kind}"}}') or 0.0

            garbage = _garbage(here / "gw.state")
            rows.append({
                "variant": variant,
                "fc published": _sample(text, 'stiction_loop_pv{loop="fc_loop"}') is not None,
                "fc protocol errors": errs("fc", "protocol"),
                "bytecount kind": f"protocol {errs('bytecount', 'protocol'):.0f} / timeout "
                                  f"{errs('bytecount', 'timeout'):.0f}",
                "tracebacks": logtext.count("Traceback"),
                "garbage": garbage,
                "behind 404": behind, "bare LF": bare})
    finally:
        plc.stop()
    return rows


def print_smaller(rows: list[dict[str, Any]]) -> None:
    for r in rows:
        print(f"{r['variant']:<7} PLC answers fc 4 for 3: published {r['fc published']}, "
              f"protocol errors {r['fc protocol errors']:.0f}; byte count beyond the frame: "
              f"{r['bytecount kind']}, tracebacks in the log {r['tracebacks']}; register "
              f"garbage, no range: {r['garbage']}; request behind a 404: {r['behind 404']} "
              f"of 2 answers; bare LF request: {r['bare LF']} of 1")


# ------------------------------------------------------------------ 5. capacity


def _readers(port: int, clients: int, rate_hz: float, seconds: float, conn: Any) -> None:
    """``clients`` SCADA-like clients, each one read of 125 registers every 1/rate s."""
    async def main() -> list[float]:
        lat: list[float] = []
        stop = time.monotonic() + seconds

        async def client(k: int) -> None:
            reader, writer = await asyncio.open_connection("127.0.0.1", port)
            next_t = time.monotonic() + random.random() / rate_hz
            tid = 0
            while time.monotonic() < stop:
                await asyncio.sleep(max(0.0, next_t - time.monotonic()))
                next_t += 1 / rate_hz
                tid += 1
                t0 = time.perf_counter()
                writer.write(read_frame(tid, 125 * (k % 300), 125))
                await reader.readexactly(259)
                lat.append(time.perf_counter() - t0)
            writer.close()

        await asyncio.gather(*(client(k) for k in range(clients)), return_exceptions=True)
        return lat

    conn.send(asyncio.run(main()))


def capacity(tree: Path, work: Path, plc_port: int) -> list[dict[str, Any]]:
    """Polls and honest reads at growing load: 64 clients (the connection limit), each a
    read of 125 registers every 1/rate s, in two processes."""
    rows = []
    from bench.attacks._arena import gateway_config, window_rows  # noqa: PLC0415

    for rate in (1.0, 10.0, 50.0, 100.0, 200.0, 400.0):
        here = work / "capacity" / f"{rate:g}"
        here.mkdir(parents=True, exist_ok=True)
        state, log = here / "gw.state", here / "gw.log"
        ports = gateway_config(here / "gw.yaml", plc_port, state=state)
        gw = start_gateway(tree, here / "gw.yaml", log)
        try:
            wait_ready(gw, log)
            wait_port(ports["modbus"])
            time.sleep(4.0)
            ctx = multiprocessing.get_context("spawn")
            pipes, procs = [], []
            seconds = 15.0
            t0 = time.time()
            for _ in range(2):
                a, b = ctx.Pipe()
                p = ctx.Process(target=_readers, args=(ports["modbus"], 32, rate, seconds, b))
                p.start()
                pipes.append(a)
                procs.append(p)
            lat = np.concatenate([np.array(a.recv()) for a in pipes])
            t1 = time.time()
            for p in procs:
                p.join(10)
        finally:
            stop_gateway(gw)
        good, gaps = window_rows(state, t0 + 2, t1)
        rows.append({"clients": 64, "rate": rate, "asked": 64 * rate,
                     "served": len(lat) / seconds,
                     "p99_ms": float(np.percentile(lat, 99) * 1e3) if len(lat) else np.nan,
                     "polls": good, "due": int(t1 - t0 - 2), "gaps": gaps})
        print(f"  ran capacity {rate:g} Hz", flush=True)
    return rows


def print_capacity(rows: list[dict[str, Any]]) -> None:
    print(f"{'clients':>7} {'reads/s each':>12} {'asked/s':>8} {'served/s':>8} "
          f"{'p99 ms':>7} {'polls/due':>9} {'gaps':>4}")
    for r in rows:
        print(f"{r['clients']:>7} {r['rate']:>12g} {r['asked']:>8.0f} {r['served']:>8.0f} "
              f"{r['p99_ms']:>7.1f} {r['polls']:>4}/{r['due']:<4} {r['gaps']:>4}")


# ------------------------------------------------------------------ all


def main() -> None:
    print(f"== hostile (issue 22): the red team's attacks on the gateway of the baseline "
          f"(before) and of this tree (after), {LOOPS:,} loops polled every 1 s from one "
          f"simulated PLC, (cores: {os.cpu_count()}) ==")
    with tempfile.TemporaryDirectory(prefix="bench-hostile22-") as tmp, \
            baseline_tree() as (commit, base):
        work = Path(tmp)
        trees = {"before": base, "after": REPO}
        print(f"before: {commit} (git archive); after: this tree", flush=True)
        plc_port = free_port()
        plc = start_plc(plc_config(work / "plc.yaml", plc_port), plc_port)
        try:
            rows = attack_table(trees, work, plc_port)
            cap = capacity(REPO, work, plc_port)
        finally:
            plc.kill()
            plc.wait()
        states = state_table(trees, work)
        disk = full_disk(trees, work)
        small = smaller(trees, work)
    print()
    print("1. attacks on the servers (22 s each; polls: GOOD rows of the window / ticks due; "
          "SCADA: answers within 2 s of the reads asked during the attack; scrape: the "
          "slowest honest scrape, ok = 200 within 2 s; answers/s: what the attacker got)")
    print_attacks(rows)
    print()
    print("2. crafted state files (20 loops)")
    print_state(states)
    print()
    print("3. failed state writes (the state folder replaced by a file, 3 s)")
    for r in disk:
        failures = "absent" if r["failures"] is None else f"{r['failures']:.0f}"
        print(f"{r['variant']:<7} stiction_state_write_failures_total {failures}; "
              f"'write failed' log lines {r['errors']}")
    print()
    print("4. smaller findings")
    print_smaller(small)
    print()
    print("5. what the result server serves honestly at 2,000 loops (this tree; 64 "
          "clients, one 125-register read each every 1/rate s, 15 s)")
    print_capacity(cap)
    print()
    after_states = [r for r in states if r["variant"] == "after"]
    checks = attack_checks(rows)
    checks["a crafted state file never stops the gateway from starting"] = all(
        r["started"] and r["status"] == 200 for r in after_states)
    checks["failed state writes are in the metrics"] = all(
        (r["failures"] or 0) > 0 for r in disk if r["variant"] == "after")
    for what, good in checks.items():
        print(f"  {'yes' if good else 'NO '}  {what}")
    print()


if __name__ == "__main__":
    main()
