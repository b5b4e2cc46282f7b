"""Before and after in one run: the gateway of a baseline commit and the gateway of this tree
side by side, each as its own ``stiction-gateway run`` process polling the same simulated
PLC of 2,000 loops at 1 s, under the same attack (bench/attacks/_attacks.py).

:func:`baseline_tree` extracts ``gateway/``, ``plcsim/`` and ``stiction/`` of the baseline
commit (``BENCH_BASELINE``, default :data:`BASELINE`: main when issue 22 was filed) with
``git archive`` into a temporary folder; a variant's process runs with that folder first on
``PYTHONPATH`` (the tree's own ``gateway`` is found before the installed one). Nothing of
the repository is changed.

:func:`run_variant` runs one gateway for a quiet phase and an attack phase and measures,
from outside: polls done (the rows of its windows in the state file it writes at SIGTERM:
GOOD rows against the ticks due in the window; gap rows), RSS (the highest during the
attack less the quiet phase's), the SCADA poller's answers and latency, honest scrapes'
time and status, the log's growth.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import resource
import signal
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench._net import free_port, wait_port
from bench.attacks._attacks import Scada, attack_process, scrape

REPO = Path(__file__).resolve().parents[2]
BASELINE = "cc81e67"  # main when issue 22 was filed
LOOPS = 2000
UNIT = REPO / "deploy" / "systemd" / "stiction-gateway.service"


@contextlib.contextmanager
def baseline_tree(ref: str | None = None) -> Iterator[tuple[str, Path]]:
    """``(commit, folder)``: the baseline's packages, extracted read-only from git."""
    ref = ref or os.environ.get("BENCH_BASELINE", BASELINE)
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", ref],
                            capture_output=True, text=True, check=True).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="bench-baseline-") as tmp:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, "gateway",
                                  "plcsim", "stiction"], capture_output=True, check=True)
        with tarfile.open(fileobj=__import__("io").BytesIO(archive.stdout)) as tar:
            tar.extractall(tmp, filter="data")
        yield commit, Path(tmp)


def unit_nofile() -> int:
    for line in UNIT.read_text().splitlines():
        if line.startswith("LimitNOFILE="):
            return int(line.split("=", 1)[1])
    return 1024


def plc_config(path: Path, port: int, loops: int = LOOPS) -> Path:
    path.write_text(yaml.safe_dump({
        "listen": f"127.0.0.1:{port}", "ts": 1.0,
        "loops": [{"name": f"L{k}", "scenario": "table4-case2" if k % 3 == 0 else "healthy",
                   "noise": 0.05} for k in range(loops)]}))
    return path


def start_plc(config: Path, port: int) -> subprocess.Popen[bytes]:
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "plc-sim", "--config",
                             str(config)], cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    wait_port(port, 60)
    return proc


def gateway_config(path: Path, plc_port: int, *, state: Path, loops: int = LOOPS,
                   persist_s: float = 5.0) -> dict[str, int]:
    """Write a gateway config polling the PLC; returns its ports."""
    ports = {"metrics": free_port(), "modbus": free_port()}
    path.write_text(yaml.safe_dump({
        "gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                    "reconnect_max_s": 1.0, "state_file": str(state),
                    "persist_interval_s": persist_s},
        "metrics": {"listen": f"127.0.0.1:{ports['metrics']}"},
        "modbus_server": {"listen": f"127.0.0.1:{ports['modbus']}", "unit_id": 1},
        "devices": [{"name": "plc", "protocol": "modbus", "host": "127.0.0.1",
                     "port": plc_port, "unit_id": 1, "poll_interval_s": 1.0,
                     "timeout_s": 1.0, "max_registers_per_request": 125}],
        "loops": [{"name": f"L{k}", "device": "plc",
                   "op": {"address": 4 * k, "type": "float32"},
                   "pv": {"address": 4 * k + 2, "type": "float32"},
                   "window_s": 120.0, "result_address": 20 * k} for k in range(loops)]}))
    return ports


def start_gateway(tree: Path, config: Path, log: Path, env: dict[str, str] | None = None
                  ) -> subprocess.Popen[bytes]:
    """``stiction-gateway run`` of ``tree`` with the unit's open-files limit (and ``env``
    added to this process's environment)."""
    nofile = unit_nofile()

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))

    env = {**os.environ, **(env or {}), "PYTHONPATH": str(tree)}
    with open(log, "ab") as out:
        return subprocess.Popen([sys.executable, "-m", "gateway.cli", "run", "--config",
                                 str(config)], cwd=tree, env=env, stdout=out,
                                stderr=subprocess.STDOUT,
                                preexec_fn=limit)  # noqa: PLW1509 - before any thread


def stop_gateway(proc: subprocess.Popen[bytes], limit_s: float = 30.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        return proc.wait(limit_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait(5)


def rss_mib(pid: int, key: str = "VmRSS") -> float:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def window_rows(state: Path, t0: float, t1: float) -> tuple[int, int]:
    """(GOOD rows, gap rows) of the first loop's window with sample times in [t0, t1)."""
    from gateway.outputs.statefile import read_state  # noqa: PLC0415 - this tree's reader

    _header, arrays = read_state(state)
    t, q = arrays["b0_t"], arrays["b0_q"][:, 0]
    inside = (t >= t0) & (t < t1)
    return int(((q == 0) & inside).sum()), int(((q == 3) & inside).sum())


def wait_ready(proc: subprocess.Popen[bytes], log: Path, limit_s: float = 60.0) -> bool:
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        if "gateway running" in log.read_text(errors="replace"):
            return True
        time.sleep(0.1)
    return False


def run_variant(tree: Path, work: Path, plc_port: int, attack: str, *, quiet_s: float = 8.0,
                attack_s: float = 22.0, scrape_every_s: float = 5.0,
                during: Callable[[dict[str, int]], dict[str, Any]] | None = None
                ) -> dict[str, Any]:
    """One gateway of ``tree`` under ``attack`` (see the module); the figures."""
    work.mkdir(parents=True, exist_ok=True)
    state, log = work / "gw.state", work / "gw.log"
    ports = gateway_config(work / "gw.yaml", plc_port, state=state)
    gw = start_gateway(tree, work / "gw.yaml", log)
    out: dict[str, Any] = {"attack": attack}
    scada = Scada(ports["modbus"])
    conn = None
    attacker = None
    try:
        if not wait_ready(gw, log):
            out["failed"] = f"did not start: {log.read_text(errors='replace')[-500:]}"
            return out
        wait_port(ports["modbus"])
        time.sleep(4.0)  # first polls; the windows start filling
        scada.start()
        q0 = time.time()
        rss_quiet = []
        while time.time() < q0 + quiet_s:
            rss_quiet.append(rss_mib(gw.pid))
            time.sleep(0.5)
        log0 = log.stat().st_size
        ctx = multiprocessing.get_context("spawn")
        conn, child = ctx.Pipe()
        attacker = ctx.Process(target=attack_process,
                               args=(attack, "127.0.0.1", ports, 20 * LOOPS, child))
        a0 = time.time()
        attacker.start()
        rss, scrapes = [], []
        next_scrape = a0 + 2.0
        while time.time() < a0 + attack_s:
            rss.append(rss_mib(gw.pid))
            if time.time() >= next_scrape:
                scrapes.append(scrape(ports["metrics"]))
                next_scrape = time.time() + scrape_every_s
            time.sleep(0.5)
        a1 = time.time()
        conn.send("stop")
        out["attacker"] = conn.recv() if conn.poll(30) else {}
        out["log_bytes"] = log.stat().st_size - log0
        time.sleep(1.0)
        scada.stop.set()
        scada.join(5)
        out["rss_quiet"] = float(np.median(rss_quiet))
        out["rss_growth"] = float(np.nanmax(rss)) - out["rss_quiet"]
        lat = scada.between(a0 + 1.0, a1)
        out["scada_answers"] = int(np.isfinite(lat).sum())
        out["scada_asked"] = len(lat)
        ok = lat[np.isfinite(lat)]
        out["scada_p99_ms"] = float(np.percentile(ok, 99) * 1e3) if len(ok) else float("nan")
        out["scrape_s"] = max((s for s, status in scrapes), default=float("nan"))
        out["scrapes_ok"] = sum(1 for s, status in scrapes if status == 200 and s <= 2.0)
        out["scrapes"] = len(scrapes)
        out["window"] = (q0, a0, a1)
    finally:
        scada.stop.set()
        if attacker is not None and attacker.is_alive():
            attacker.kill()
        out["exit"] = stop_gateway(gw)
    q0, a0, a1 = out["window"]
    good_q, _gaps_q = window_rows(state, q0, a0)
    good, gaps = window_rows(state, a0, a1)
    out["polls_quiet"] = good_q / (a0 - q0)
    out["polls"] = good / (a1 - a0)
    out["ticks"] = int((a1 - a0) // 1.0)  # ticks due in the window (1 s polls)
    out["ratio"] = good / out["ticks"]
    out["gaps"] = gaps
    out["attack_rate"] = out.get("attacker", {}).get("answers", 0) / (a1 - a0)
    out["log"] = log.read_text(errors="replace")
    return out
