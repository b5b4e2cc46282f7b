"""Soak test (``make soak``, not part of the test suite): 1,000 simulated loops for 10 minutes
while the simulated PLCs are killed and restarted and the gateway gets SIGHUPs.

Two ``stiction-gateway plc-sim`` processes (``plcA``, ``plcB``) serve half of the loops each;
one ``stiction-gateway run`` process polls both every second (Ts 1 s, real time) under a
fake systemd (a datagram ``$NOTIFY_SOCKET`` with a watchdog). Every ``--kill-every`` seconds
one PLC (alternately) is SIGKILLed and restarted ``--down`` seconds later; every
``--hup-every`` seconds the gateway is sent SIGHUP (the config alternates between two
analysis intervals, so each reload really applies a new config). At the end the gateway is
stopped with SIGTERM and its state file - which holds every sample of the run, the windows
being longer than the run - is the record of what was received:

* samples expected (loops × ticks of each device) vs received (GOOD samples);
* gaps: runs of ticks without good samples, each matched to the PLC outage that explains
  it (from the kill to the restart plus the reconnect backoff); unexplained gaps are listed;
* restarts survived (PLC kills, SIGHUPs each acknowledged RELOADING=1 → READY=1), the
  gateway's exit status, watchdog pings, errors in its log;
* RSS of the gateway process (and of its analysis workers) at start, during and at the end.

``python -m bench.field.soak --minutes 1`` gives a quick run.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench._net import free_port, wait_port
from gateway.core.points import Quality
from gateway.outputs.statefile.format import read_state

PY = sys.executable
SCENARIOS = ("table4-case2", "healthy", "table5-case2", "disturbance", "aggressive-tuning")
RECONNECT_MAX_S = 5.0


def rss_kib(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(x) for x in text.split()]


class Plc:
    def __init__(self, name: str, port: int, loops: int, first: int, tmp: Path) -> None:
        self.name, self.port = name, port
        self.cfg = tmp / f"{name}.yaml"
        self.cfg.write_text(yaml.safe_dump({
            "listen": f"127.0.0.1:{port}", "ts": 1.0, "time_scale": 1.0, "seed": first,
            "loops": [{"name": f"{name}_{k:04d}", "scenario": SCENARIOS[(first + k) % 5],
                       "noise": 0.05} for k in range(loops)]}))
        self.proc: subprocess.Popen[bytes] | None = None
        self.outages: list[list[float]] = []  # [kill wall time, restart wall time]

    def start(self) -> None:
        self.proc = subprocess.Popen([PY, "-m", "gateway.cli", "plc-sim", "--config",
                                      str(self.cfg)], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        wait_port(self.port, limit_s=60.0)

    def kill(self) -> None:
        assert self.proc is not None
        self.outages.append([time.time(), float("nan")])
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(10)

    def restart(self) -> None:
        self.start()
        self.outages[-1][1] = time.time()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(10)
            if self.proc.poll() is None:
                self.proc.kill()


def gateway_config(plcs: list[Plc], per_plc: int, state: Path, metrics_port: int,
                   analysis_s: float) -> dict[str, Any]:
    loops = []
    for d, plc in enumerate(plcs):
        for k in range(per_plc):
            i = d * per_plc + k
            loops.append({"name": f"{plc.name}_{k:04d}", "device": plc.name,
                          "op": {"address": 4 * k, "type": "float32"},
                          "pv": {"address": 4 * k + 2, "type": "float32"},
                          "window_s": 1200.0, "result_address": 20 * i})
    return {
        "gateway": {"analysis_interval_s": analysis_s, "state_file": str(state),
                    "persist_interval_s": 60.0, "reconnect_max_s": RECONNECT_MAX_S,
                    "analysis_workers": 1},
        "metrics": {"listen": f"127.0.0.1:{metrics_port}"},
        "modbus_server": {"listen": "127.0.0.1:0"},
        "devices": [{"name": p.name, "protocol": "modbus", "host": "127.0.0.1",
                     "port": p.port, "unit_id": 1, "poll_interval_s": 1.0, "timeout_s": 0.5,
                     "max_registers_per_request": 125} for p in plcs],
        "loops": loops,
    }


class Notify:
    """systemd's side of sd_notify: records every datagram with its time."""

    def __init__(self, path: Path) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(str(path))
        self.sock.settimeout(0.5)
        self.path = path
        self.messages: list[tuple[float, str]] = []
        self._run = True
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        while self._run:
            try:
                self.messages.append((time.time(), self.sock.recv(65536).decode()))
            except (TimeoutError, OSError):
                continue

    def count(self, prefix: str) -> int:
        return sum(1 for _, m in self.messages if m.startswith(prefix))

    def wait(self, prefix: str, after: int, limit_s: float = 120.0) -> None:
        deadline = time.monotonic() + limit_s
        while self.count(prefix) <= after:
            if time.monotonic() > deadline:
                raise TimeoutError(prefix)
            time.sleep(0.05)

    def close(self) -> None:
        self._run = False
        self.thread.join(2)
        self.sock.close()


def gaps(t: np.ndarray, good_rows: np.ndarray) -> list[tuple[float, float, int]]:
    """(start time, end time, ticks) of each run of rows without good samples."""
    out = []
    bad = ~good_rows
    edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.view(np.int8), [0]))))
    for b, e in edges.reshape(-1, 2):
        out.append((float(t[b]), float(t[e - 1]), int(e - b)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.field.soak",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--loops", type=int, default=1000)
    ap.add_argument("--kill-every", type=float, default=75.0)
    ap.add_argument("--down", type=float, default=10.0)
    ap.add_argument("--hup-every", type=float, default=50.0)
    args = ap.parse_args(argv)
    duration = args.minutes * 60.0
    per_plc = args.loops // 2
    tmp = Path(tempfile.mkdtemp(prefix="stiction-soak-"))
    plcs = [Plc("plcA", free_port(), per_plc, 0, tmp), Plc("plcB", free_port(), per_plc, 1, tmp)]
    state, cfg_path, log = tmp / "gw.state", tmp / "gw.yaml", tmp / "gw.log"
    metrics_port = free_port()
    notify = Notify(tmp / "notify.sock")
    print(f"soak: {2 * per_plc} loops on 2 simulated PLCs, Ts 1 s, {duration / 60:g} min; "
          f"PLC killed every {args.kill_every:g} s for {args.down:g} s, SIGHUP every "
          f"{args.hup_every:g} s; work dir {tmp}", flush=True)
    for p in plcs:
        p.start()
    cfg_path.write_text(yaml.safe_dump(gateway_config(plcs, per_plc, state, metrics_port, 60.0)))
    env = {**os.environ, "NOTIFY_SOCKET": str(notify.path), "WATCHDOG_USEC": "10000000"}
    with open(log, "wb") as f:
        gw = subprocess.Popen([PY, "-m", "gateway.cli", "run", "--config", str(cfg_path)],
                              stdout=f, stderr=subprocess.STDOUT, env=env)
    rss: list[tuple[float, int, int]] = []
    hups = kills = 0
    try:
        notify.wait("READY=1", 0)
        t0 = time.time()
        start_mono = time.monotonic()
        rss.append((0.0, rss_kib(gw.pid), sum(rss_kib(c) for c in children(gw.pid))))
        print(f"gateway READY after start; RSS {rss[0][1] / 1024:.0f} MiB "
              f"(workers {rss[0][2] / 1024:.0f} MiB)", flush=True)
        next_kill, next_hup, next_rss = args.kill_every, args.hup_every, 60.0
        down: Plc | None = None
        up_at = 0.0
        while (el := time.monotonic() - start_mono) < duration:
            if gw.poll() is not None:
                raise RuntimeError(f"gateway exited with {gw.returncode}")
            if down is None and el >= next_kill and el < duration - args.down - 20:
                down = plcs[kills % 2]
                down.kill()
                kills += 1
                up_at = el + args.down
                next_kill += args.kill_every
                print(f"[{el:6.1f} s] killed {down.name}", flush=True)
            if down is not None and el >= up_at:
                down.restart()
                print(f"[{el:6.1f} s] restarted {down.name}", flush=True)
                down = None
            if el >= next_hup:
                before = notify.count("READY=1")
                cfg_path.write_text(yaml.safe_dump(gateway_config(
                    plcs, per_plc, state, metrics_port, 60.0 + (hups + 1) % 2)))
                gw.send_signal(signal.SIGHUP)
                hups += 1
                notify.wait("READY=1", before, limit_s=60)
                print(f"[{el:6.1f} s] SIGHUP {hups}: RELOADING then READY in "
                      f"{time.monotonic() - start_mono - el:.2f} s", flush=True)
                next_hup += args.hup_every
            if el >= next_rss:
                rss.append((el, rss_kib(gw.pid), sum(rss_kib(c) for c in children(gw.pid))))
                print(f"[{el:6.1f} s] RSS {rss[-1][1] / 1024:.0f} MiB "
                      f"(workers {rss[-1][2] / 1024:.0f} MiB)", flush=True)
                next_rss += 60.0
            time.sleep(0.1)
        rss.append((time.monotonic() - start_mono, rss_kib(gw.pid),
                    sum(rss_kib(c) for c in children(gw.pid))))
        with urllib.request.urlopen(f"http://127.0.0.1:{metrics_port}/metrics", timeout=5) as r:
            metrics = r.read().decode()
        t_end = time.time()
        t_term = time.monotonic()
        gw.send_signal(signal.SIGTERM)
        code = gw.wait(60)
        shutdown_s = time.monotonic() - t_term
    finally:
        if gw.poll() is None:
            gw.kill()
        for p in plcs:
            p.stop()
        notify.close()

    # ---------------------------------------------------------------- the record
    header, arrays = read_state(state)
    text = log.read_text(errors="replace")
    print("\n== soak result ==")
    print(f"duration {duration:.0f} s; gateway exit status {code} after SIGTERM in "
          f"{shutdown_s:.2f} s")
    total_exp = total_got = 0
    unexplained: list[str] = []
    n_gaps = 0
    for k, bank in enumerate(header["banks"]):
        dev = bank["loops"][0]["name"].split("_")[0]
        plc = next(p for p in plcs if p.name == dev)
        t = arrays[f"b{k}_t"]
        q = arrays[f"b{k}_q"]
        sel = (t >= t0) & (t <= t_end)
        t, q = t[sel], q[sel]
        n_loops = q.shape[1]
        ticks = round((t_end - t0) / bank["ts"])
        exp = ticks * n_loops
        got = int((q == Quality.GOOD).sum())
        total_exp += exp
        total_got += got
        good_rows = (q == Quality.GOOD).all(axis=1)
        partial = int(((q == Quality.GOOD).any(axis=1) & ~good_rows).sum())
        print(f"{dev}: {n_loops} loops, {ticks} ticks, rows in window {len(t)}; samples "
              f"expected {exp}, received {got} ({got / exp:.2%}); rows with some loops "
              f"missing {partial}")
        for g0, g1, n in gaps(t, good_rows):
            n_gaps += 1
            why = None
            for kill, restart in plc.outages:
                if kill - 2.0 <= g0 and g1 <= restart + RECONNECT_MAX_S + 2.0:
                    why = (f"PLC killed at +{kill - t0:.1f} s, restarted at "
                           f"+{restart - t0:.1f} s")
            line = f"  gap +{g0 - t0:7.1f} s .. +{g1 - t0:7.1f} s, {n:3d} ticks: " + \
                (why or "UNEXPLAINED")
            print(line)
            if why is None:
                unexplained.append(line)
    print(f"total: samples expected {total_exp}, received {total_got} "
          f"({total_got / total_exp:.2%}); gaps {n_gaps}, unexplained {len(unexplained)}")
    kills_done = sum(len(p.outages) for p in plcs)
    print(f"restarts survived: {kills_done} PLC kills+restarts, {hups} SIGHUP reloads "
          f"({notify.count('RELOADING=1')} RELOADING=1, {notify.count('READY=1')} READY=1 "
          f"incl. start-up), {notify.count('WATCHDOG=1')} watchdog pings, "
          f"STOPPING=1 sent: {notify.count('STOPPING=1') == 1}")
    up = [line for line in metrics.splitlines() if line.startswith("stiction_device_up")]
    print("at the end: " + "; ".join(up))
    errors = [line for line in text.splitlines() if " ERROR " in line or "Traceback" in line]
    downs = [line for line in text.splitlines() if ": down (" in line]
    recov = [line for line in text.splitlines() if ": recovered" in line]
    print(f"gateway log: {len(downs)} 'down' lines, {len(recov)} 'recovered' lines, "
          f"{len(errors)} ERROR/Traceback lines")
    for line in errors[:10]:
        print("  " + line)
    print("RSS of the gateway process (MiB) / analysis workers (MiB):")
    for el, main_kib, workers_kib in rss:
        print(f"  +{el:6.1f} s  {main_kib / 1024:7.1f}  {workers_kib / 1024:7.1f}")
    growth = (rss[-1][1] - rss[1][1]) / 1024 if len(rss) > 2 else float("nan")
    print(f"RSS start {rss[0][1] / 1024:.1f} MiB, end {rss[-1][1] / 1024:.1f} MiB "
          f"(growth after the first minute {growth:+.1f} MiB)")
    ok = (code == 0 and not unexplained and not errors and total_got > 0)
    print("SOAK " + ("PASSED" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
