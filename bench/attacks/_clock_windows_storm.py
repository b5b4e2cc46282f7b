"""Issue 31 in ``python -m bench hostile``: three cases of a third round of attacks, each on
the gateway of the baseline commit (before) and of this tree (after), side by side
(``git archive`` of the baseline as bench/attacks/_arena.py does; ``BENCH_BASELINE31`` names
another commit).

1. **clock**: the wall clock stepped back an hour across a clean stop, then two hours
   across a SIGKILL (bench/attacks/_clock.py, libfaketime): the gap each restart leaves in the
   window (0: the samples before and after are joined), the sequence numbers SCADA reads
   around the kill, whether the analysis bridges an outage, the warning line and metric.
2. **short windows**: a simulated PLC of 8 healthy and 4 sticky loops at 20x real time,
   every loop's window (1 h) far from full, analysed every 10 process seconds from the
   start, then an outage of the PLC (2 s, 40 polls) and its restart: what the journal says
   each loop's verdict was, round after round. How often a healthy loop is called
   ``stiction``, how often a sticky loop's verdict changes, whether a sticky loop says
   ``stiction`` again after the outage. (Item 2 of the issue, a verdict only once a window
   can be judged, is built elsewhere: this case measures whatever the tree does.)
3. **reconnect storm**: 70 clients reading 20 registers every 50 ms and reconnecting at
   once when closed (the result server holds 64), and a SCADA client opening a new
   connection for each of its reads (4 a second): how many it gets.
"""

from __future__ import annotations

import collections
import contextlib
import multiprocessing
import os
import re
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
from bench.attacks._arena import REPO, baseline_tree, start_gateway, stop_gateway, wait_ready
from bench.attacks._attacks import Scada, attack_process
from bench.attacks._clock import clock_case, faketime, summary

BASELINE = "3dfa8c7"  # main when issue 31 was filed
HEALTHY, STICKY = 8, 4
SCALE = 20.0  # process seconds per wall second (short-window case)
STORM_LOOPS = 100
STORM_S = 20.0


def _plc(path: Path, port: int, loops: list[tuple[str, str]], *, ts: float = 1.0,
         scale: float = 1.0) -> subprocess.Popen[bytes]:
    path.write_text(yaml.safe_dump({
        "listen": f"127.0.0.1:{port}", "ts": ts, "time_scale": scale,
        "loops": [{"name": n, "scenario": sc, "noise": 0.05} for n, sc in loops]}))
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "plc-sim", "--config",
                             str(path)], cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    wait_port(port, 60)
    return proc


def _gateway_yaml(path: Path, plc_port: int, names: list[str], *, window_s: float,
                  analysis_s: float, scale: float = 1.0) -> dict[str, int]:
    ports = {"metrics": free_port(), "modbus": free_port()}
    path.write_text(yaml.safe_dump({
        "gateway": {"analysis_interval_s": analysis_s, "analysis_workers": 1,
                    "reconnect_max_s": 0.5, "time_scale": scale,
                    "state_file": str(path.parent / "gw.state")},
        "metrics": {"listen": f"127.0.0.1:{ports['metrics']}"},
        "modbus_server": {"listen": f"127.0.0.1:{ports['modbus']}", "unit_id": 1},
        "plant": {"enabled": False},
        "devices": [{"name": "plc", "protocol": "modbus", "host": "127.0.0.1",
                     "port": plc_port, "unit_id": 1, "poll_interval_s": 1.0,
                     "timeout_s": 1.0, "max_registers_per_request": 125}],
        "loops": [{"name": n, "device": "plc", "op": {"address": 4 * k, "type": "float32"},
                   "pv": {"address": 4 * k + 2, "type": "float32"}, "window_s": window_s,
                   "result_address": 20 * k} for k, n in enumerate(names)]}))
    return ports


# ------------------------------------------------------------------ 1. the clock


def clock_rows(trees: dict[str, Path], work: Path) -> list[dict[str, Any]]:
    env2, env3 = faketime(3600), faketime(7200)
    if env2 is None or env3 is None:
        return [{"variant": v, "failed": "libfaketime not installed (apt-get install "
                 "libfaketime)"} for v in trees]
    from gateway.outputs.statefile.restore import UNKNOWN_DOWNTIME_ROWS  # noqa: PLC0415

    rows = []
    for variant, tree in trees.items():
        try:
            out = clock_case(tree, work / "clock" / variant, env2, env3)
        except RuntimeError as exc:
            rows.append({"variant": variant, "failed": str(exc)[:200]})
            continue
        rows.append({"variant": variant, **summary(out, UNKNOWN_DOWNTIME_ROWS),
                     "seq2": out["seq2"], "seq3": out["seq3"]})
        print(f"  ran clock {variant}", flush=True)
    return rows


def table(rows: list[dict[str, Any]], cols: list[tuple[str, Any]]) -> None:
    """Print ``rows`` (one per gateway, ``variant`` first) under ``cols``: (title, the
    cell of a row as text), each right-aligned to its title; a failed row says why."""
    widths = [max(len(t), 7) for t, _ in cols]
    print(f"{'gateway':<7} " + " ".join(f"{t:>{w}}" for (t, _), w in zip(cols, widths,
                                                                          strict=True)))
    for r in rows:
        cells = [r["failed"]] if "failed" in r else \
            [f"{cell(r):>{w}}" for (_, cell), w in zip(cols, widths, strict=True)]
        print(f"{r['variant']:<7} " + " ".join(cells))


def _yes(x: bool) -> str:
    return "yes" if x else "no"


def print_clock(rows: list[dict[str, Any]]) -> None:
    table(rows, [
        ("gap clean", lambda r: str(r["gap_clean"])), ("gap kill", lambda r: str(r["gap_kill"])),
        ("seq before kill", lambda r: str(r["seq_last_before_kill"])),
        ("seq after", lambda r: str(r["seq_first_after"])),
        ("seq back", lambda r: _yes(r["seq_back"])),
        ("analysed", lambda r: f"{r['segment']} of {r['since_restart']}"),
        ("warning", lambda r: _yes(r["warned"])),
        ("clock_back_s", lambda r: "absent" if r["clock_back"] is None
         else f"{r['clock_back']:.0f}")])


# ------------------------------------------------------------------ 2. short windows

_VERDICT = re.compile(r"gateway\.analysis: loop (\S+): verdict (\S+) \(was (\S+)\)")


def short_window_run(tree: Path, work: Path) -> dict[str, Any]:
    """The short-window case (see the module) with the gateway of ``tree``."""
    work.mkdir(parents=True, exist_ok=True)
    loops = [(f"H{k}", "healthy") for k in range(HEALTHY)] + \
        [(f"S{k}", "table4-case2") for k in range(STICKY)]
    plc_port = free_port()
    plc = _plc(work / "plc.yaml", plc_port, loops, scale=SCALE)
    log = work / "gw.log"
    ports = _gateway_yaml(work / "gw.yaml", plc_port, [n for n, _ in loops], window_s=3600.0,
                          analysis_s=10.0, scale=SCALE)
    gw = start_gateway(tree, work / "gw.yaml", log)
    out: dict[str, Any] = {}
    try:
        if not wait_ready(gw, log, 120.0):
            return {"failed": f"did not start: {log.read_text(errors='replace')[-300:]}"}
        time.sleep(20.0)  # 400 process s: windows of up to 400 samples of 3,600
        plc.kill()
        plc.wait()
        out["outage_at"] = log.stat().st_size
        time.sleep(2.0)  # 40 polls: the windows restart after it
        plc = _plc(work / "plc.yaml", plc_port, loops, scale=SCALE)
        time.sleep(15.0)
        out["missed"] = _scrape_sample(ports["metrics"],
                                       'stiction_poll_missed_ticks_total{device="plc"}')
    finally:
        stop_gateway(gw)
        plc.kill()
        plc.wait()
    text = log.read_text(errors="replace")
    changes: dict[str, list[str]] = collections.defaultdict(list)
    after_outage: dict[str, list[str]] = collections.defaultdict(list)
    offset = 0
    for line in text.splitlines(keepends=True):
        m = _VERDICT.search(line)
        if m:
            changes[m.group(1)].append(m.group(2))
            if offset >= out["outage_at"]:
                after_outage[m.group(1)].append(m.group(2))
        offset += len(line.encode())
    healthy = [n for n, sc in loops if sc == "healthy"]
    sticky = [n for n, sc in loops if sc != "healthy"]
    return {
        "missed": out["missed"],
        "healthy_called": sum("stiction" in changes[n] for n in healthy),
        "healthy_calls": sum(changes[n].count("stiction") for n in healthy),
        "sticky_changes": sum(len(changes[n]) for n in sticky) / len(sticky),
        "sticky_called": sum("stiction" in changes[n] for n in sticky),
        "sticky_lost": sum("stiction" in changes[n] and "stiction" in
                           changes[n][:len(changes[n]) - len(after_outage[n])]
                           and after_outage[n] and after_outage[n][-1] != "stiction"
                           for n in sticky),
        "sticky_story": {n: changes[n] for n in sticky[:2]},
        "healthy_story": {n: changes[n] for n in healthy if "stiction" in changes[n]},
    }


def print_short(rows: list[dict[str, Any]]) -> None:
    table(rows, [
        ("healthy called stiction", lambda r: f"{r['healthy_called']} of {HEALTHY}"),
        ("calls", lambda r: str(r["healthy_calls"])),
        ("sticky called", lambda r: f"{r['sticky_called']} of {STICKY}"),
        ("verdict changes/sticky loop", lambda r: f"{r['sticky_changes']:.1f}"),
        ("sticky not stiction after the outage", lambda r: f"{r['sticky_lost']} of {STICKY}"),
        ("missed ticks", lambda r: "?" if r["missed"] is None else f"{r['missed']:.0f}")])
    for r in rows:
        if "failed" not in r:
            print(f"  {r['variant']}: sticky loops' verdicts in turn {r['sticky_story']}; "
                  f"healthy loops called stiction {r['healthy_story'] or 'none'}")


# ------------------------------------------------------------------ 3. reconnect storm


def storm_run(tree: Path, work: Path, plc_port: int) -> dict[str, Any]:
    """The reconnect-storm case (see the module) with the gateway of ``tree``."""
    work.mkdir(parents=True, exist_ok=True)
    log = work / "gw.log"
    ports = _gateway_yaml(work / "gw.yaml", plc_port,
                          [f"L{k}" for k in range(STORM_LOOPS)], window_s=120.0,
                          analysis_s=1e6)
    gw = start_gateway(tree, work / "gw.yaml", log)
    scada = Scada(ports["modbus"], period_s=0.25, timeout_s=2.0, per_read=True)
    attacker = None
    out: dict[str, Any] = {}
    try:
        if not wait_ready(gw, log, 120.0):
            return {"failed": f"did not start: {log.read_text(errors='replace')[-300:]}"}
        wait_port(ports["modbus"])
        ctx = multiprocessing.get_context("spawn")
        conn, child = ctx.Pipe()
        attacker = ctx.Process(target=attack_process,
                               args=("busy-50ms", "127.0.0.1", ports, 20 * STORM_LOOPS,
                                     child))
        attacker.start()
        time.sleep(3.0)  # the storm builds up
        scada.start()
        t0 = time.time()
        time.sleep(STORM_S)
        t1 = time.time()
        scada.stop.set()
        scada.join(5)
        conn.send("stop")
        out["attacker"] = conn.recv() if conn.poll(30) else {}
        lat = scada.between(t0, t1)
        out["asked"], out["answered"] = len(lat), int(np.isfinite(lat).sum())
        out["closed"] = {r: _scrape_sample(ports["metrics"],
                                           "stiction_server_connections_closed_total"
                                           f'{{reason="{r}",server="modbus"}}')
                         for r in ("limit", "busiest")}
        out["storm_rate"] = out["attacker"].get("answers", 0) / (t1 - t0 + 3.0)
    finally:
        scada.stop.set()
        if attacker is not None and attacker.is_alive():
            attacker.kill()
        stop_gateway(gw)
    return out


def _scrape_sample(port: int, series: str) -> float | None:
    """One sample of the gateway's /metrics (None: absent, or no answer)."""
    with contextlib.suppress(OSError), \
            urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=30) as rsp:
        for line in rsp.read().decode().splitlines():
            if line.startswith(series + " "):
                return float(line.split()[-1])
    return None


def print_storm(rows: list[dict[str, Any]]) -> None:
    table(rows, [
        ("SCADA answered", lambda r: f"{r['answered']} of {r['asked']}"),
        ("storm reads/s", lambda r: f"{r['storm_rate']:,.0f}"),
        ("closed: limit", lambda r: f"{r.get('closed', {}).get('limit') or 0:,.0f}"),
        ("busiest", lambda r: f"{r.get('closed', {}).get('busiest') or 0:,.0f}")])


# ------------------------------------------------------------------ the run


def main() -> None:
    print(f"== hostile (issue 31): a wall clock stepped back, windows too short to judge, a "
          f"reconnect storm; the gateway of the baseline (before) and of this tree (after) "
          f"(cores: {os.cpu_count()}) ==")
    with tempfile.TemporaryDirectory(prefix="bench-hostile31-") as tmp, \
            baseline_tree(os.environ.get("BENCH_BASELINE31", BASELINE)) as (commit, base):
        work = Path(tmp)
        trees = {"before": base, "after": REPO}
        print(f"before: {commit} (git archive); after: this tree", flush=True)
        clock = clock_rows(trees, work)
        short = []
        for variant, tree in trees.items():
            short.append({"variant": variant, **short_window_run(tree, work / "short" /
                                                                  variant)})
            print(f"  ran short windows {variant}", flush=True)
        plc_port = free_port()
        plc = _plc(work / "storm-plc.yaml", plc_port,
                   [(f"L{k}", "healthy") for k in range(STORM_LOOPS)])
        try:
            storm = []
            for variant, tree in trees.items():
                storm.append({"variant": variant,
                              **storm_run(tree, work / "storm" / variant, plc_port)})
                print(f"  ran reconnect storm {variant}", flush=True)
        finally:
            plc.kill()
            plc.wait()
    print()
    print("1. the wall clock an hour back after a clean stop, two hours back after a SIGKILL "
          "(gaps: MISSING rows after each restart, 0 = joined; seq: what SCADA read last "
          "before the kill and first after; analysed: samples the analysis sees, of those "
          "since the last restart)")
    print_clock(clock)
    print()
    print(f"2. short windows: {HEALTHY} healthy and {STICKY} sticky loops at {SCALE:.0f}x, "
          f"windows of 1 h analysed every 10 s from the start, a 2 s (40-poll) PLC outage "
          f"after 20 s, 15 s more (verdicts from the journal's change lines)")
    print_short(short)
    print()
    print(f"3. reconnect storm: 70 clients reading every 50 ms, reconnecting at once (64 "
          f"slots); a SCADA client with a new connection for each read, 4 a second, "
          f"{STORM_S:.0f} s")
    print_storm(storm)
    print()
