"""Machinery of the scale benchmarks: simulated PLCs and the gateway as separate processes.

:func:`run_scale` starts N simulated PLCs (``python -m bench.speed._scale sim CONFIG``, each a
:class:`plcsim.sim.PlcSim` serving its share of M loops on 127.0.0.1) and one gateway
(``python -m bench.speed._scale gateway SPEC``, a real :class:`gateway.runtime.gateway.Gateway`
polling all of them), lets the gateway poll for ``duration`` seconds and collects what each
child measured about itself: the gateway its own CPU time (``time.process_time``, all its
threads, not its analysis workers), RSS, poll start times and the samples in its windows; each
PLC the requests it served and the time its steps took. Every child is killed on exit,
whatever happens.

Figures (see :class:`ScaleResult`):

* requests per poll cycle: requests the PLCs answered / polls, summed over devices, beside
  the minimum the register layout allows (:func:`min_requests`: the fewest reads of at most
  ``max_registers_per_request`` registers that cover every used register);
* poll start jitter: per tick, start time minus due time (due = first start + k × period);
* samples expected vs stored: ticks due × loops against GOOD samples in the windows, over
  the whole run (a sample whose poll started more than half a period late counts as lost);
* with ``analysis=True`` the windows are first filled with ``window_s`` of simulated data and
  one full analysis round runs while polling goes on; jitter is then also reported for the
  ticks that started during the round.

The gateway config is built from the per-PLC configs that
:func:`plcsim.gateway_yaml.gateway_config` writes, joined into one document whose result blocks
:func:`plcsim.gateway_yaml.assign_result_blocks` numbers across all loops (3,276 per result unit
id: 10,000 loops use unit ids 1-4), and validated as a whole by
:func:`gateway.config.parse_config`: the gateway runs a real config, result server included.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import logging
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gateway.config import Config, parse_config
from gateway.core.points import Quality
from gateway.runtime.gateway import Gateway
from plcsim import PlcSim, assign_result_blocks, load_sim_config
from plcsim import gateway_config as sim_gateway_config
from plcsim.sim import build_banks

REGISTERS_PER_LOOP = 4
MAX_REGISTERS = 125
HUGE_INTERVAL_S = 1e9  # "never": analysis rounds are started by the bench itself
SCENARIO_MIX = ("table4-case1", "table4-case2", "table5-case1", "table5-case2", "table6",
                "table7", "table9", "healthy", "aggressive-tuning", "disturbance")
"""Round-robin scenario of loop i (7 of 10 sticky: a pessimistic plant)."""


def default_plcs(loops: int) -> int:
    """PLCs for M loops: 500 loops (2,000 registers) per PLC, at least 1, 20 for 10,000."""
    return max(1, math.ceil(loops / 500))


def min_requests(addresses: Sequence[tuple[int, int]], max_registers: int = MAX_REGISTERS
                 ) -> int:
    """Fewest reads of at most ``max_registers`` consecutive registers covering every
    ``(address, width)`` span (greedy from the lowest uncovered register: optimal on a line).
    Spans of one table only."""
    used = sorted({a + k for a, w in addresses for k in range(w)})
    n = 0
    end = -1
    for r in used:
        if r >= end:
            n += 1
            end = r + max_registers
    return n


def rss_bytes(pid: int | str = "self") -> tuple[int, int]:
    """(VmRSS, VmHWM) of a process, bytes (Linux /proc)."""
    out = {"VmRSS": 0, "VmHWM": 0}
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            key, _, rest = line.partition(":")
            if key in out:
                out[key] = int(rest.split()[0]) * 1024
    return out["VmRSS"], out["VmHWM"]


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc), 0 if gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values: Sequence[float], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else math.nan


# ------------------------------------------------------------------------ configs


def sim_config(plc: int, first_loop: int, n_loops: int, *, window_s: float,
               noise: float = 0.05) -> dict[str, Any]:
    """The plc-sim config of PLC ``plc`` serving loops first_loop .. first_loop+n-1."""
    return {
        "listen": "127.0.0.1:0", "unit_id": 1, "ts": 1.0, "time_scale": 1.0,
        "seed": plc, "word_order": "big",
        "loops": [{"name": f"P{plc:02d}L{i:05d}",
                   "scenario": SCENARIO_MIX[i % len(SCENARIO_MIX)], "noise": noise,
                   "window_s": window_s}
                  for i in range(first_loop, first_loop + n_loops)],
    }


def gateway_config(sim_paths: Sequence[str], ports: Sequence[int], *, workers: int = 0
                   ) -> Config:
    """One gateway :class:`~gateway.config.Config` reading every simulated PLC: the
    per-PLC configs joined into one document (result blocks renumbered across all loops,
    3,276 per result unit id) and validated as a whole."""
    devices: list[Any] = []
    loops: list[Any] = []
    data: dict[str, Any] = {}
    for k, (path, port) in enumerate(zip(sim_paths, ports, strict=True)):
        data = sim_gateway_config(load_sim_config(path), port=port,
                                  analysis_interval_s=HUGE_INTERVAL_S,
                                  metrics_listen="127.0.0.1:0", result_listen="127.0.0.1:0")
        name = f"plc{k:02d}"
        data["devices"][0]["name"] = name
        for lp in data["loops"]:
            lp["device"] = name
        devices += data["devices"]
        loops += data["loops"]
    assign_result_blocks(loops, data["modbus_server"]["unit_id"])
    data["gateway"]["analysis_workers"] = workers
    return parse_config({**data, "devices": devices, "loops": loops}, "bench")


# ------------------------------------------------------------------------ child: PLC


async def _sim_child(path: str) -> None:
    cfg = load_sim_config(path)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGTERM, stop.set)
    async with PlcSim(cfg) as sim:
        step_times: list[float] = []
        plain_step = sim.step

        def timed_step() -> None:
            t0 = time.perf_counter()
            plain_step()
            step_times.append(time.perf_counter() - t0)

        sim.step = timed_step  # type: ignore[method-assign]
        cpu0, wall0 = time.process_time(), time.perf_counter()
        print(json.dumps({"port": sim.port}), flush=True)
        await stop.wait()
        stats = {"requests": sim.server.requests, "steps": sim.steps,
                 "cpu_s": time.process_time() - cpu0, "wall_s": time.perf_counter() - wall0,
                 "step_median_s": statistics.median(step_times) if step_times else math.nan,
                 "step_max_s": max(step_times, default=math.nan),
                 "rss": rss_bytes()[0]}
    print(json.dumps(stats), flush=True)


# ------------------------------------------------------------------------ child: gateway


def _prefill(banks: Sequence[Any], sim_path: str, t_end: float) -> float:
    """Fill every window bank with simulated samples ending at ``t_end`` (Unix s); the loops
    of the first PLC are simulated once and their windows copied to the other banks
    (same scenario mix). Returns the seconds it took."""
    t0 = time.perf_counter()
    cfg = load_sim_config(sim_path)
    size = max(b.size for b in banks)
    n = len(cfg.loops)
    op = np.empty((size, n), dtype=np.float32)
    pv = np.empty((size, n), dtype=np.float32)
    sims = build_banks(cfg)
    for k in range(size):
        for b in sims:
            t = b.bank.t
            out = b.bank.step(b.sp_base + np.where(t >= b.sp_time, b.sp_step, 0.0))
            op[k, b.rows] = out.op
            pv[k, b.rows] = out.pv
    for bank in banks:
        cols = np.arange(len(bank.loops)) % n
        bank.op[:] = op[-bank.size:, cols]
        bank.pv[:] = pv[-bank.size:, cols]
        bank.quality[:] = Quality.GOOD
        bank.t[:] = t_end - np.arange(bank.size, 0, -1, dtype=np.float64)
        bank.head, bank.count = 0, bank.size
    return time.perf_counter() - t0


def _jitter(starts: Sequence[float], period: float) -> tuple[float, list[tuple[float, float]]]:
    """(first start, [(start, lateness)]) with due times first + k × period."""
    if not starts:
        return math.nan, []
    t0 = starts[0]
    out = []
    for t in starts:
        k = math.floor((t - t0 + 0.01) / period)
        out.append((t, t - (t0 + k * period)))
    return t0, out


async def _gateway_child(spec: dict[str, Any]) -> dict[str, Any]:
    rss_start = rss_bytes()[0]
    config = gateway_config(spec["sims"], spec["ports"], workers=spec.get("workers", 0))
    gw = Gateway(config, serve_http=True)
    banks = [s.bank for p in gw.pollers for s in p.groups]
    rss_banks = rss_bytes()[0]
    window_bytes = sum(b.nbytes for b in banks)
    samples_capacity = sum(b.size * len(b.loops) for b in banks)
    start_unix = time.time()
    prefill_s = _prefill(banks, spec["sims"][0], start_unix) if spec.get("analysis") else 0.0
    loop = asyncio.get_running_loop()
    period = config.devices[0].poll_interval_s
    async with gw:
        t_begin = loop.time()
        off = time.time() - t_begin
        await asyncio.sleep(spec["warmup"])
        cpu0, wall0 = time.process_time(), loop.time()
        round_span = (math.nan, math.nan)
        round_cpu = math.nan
        worker_cpu = math.nan
        loops_analysed = 0
        if spec.get("analysis"):
            pool = gw.scheduler._pool
            worker_pids = list(pool._processes) if pool is not None else []
            w0 = sum(cpu_seconds(p) for p in worker_pids)
            c0, r0 = time.process_time(), loop.time()
            loops_analysed = await gw.scheduler.run_round()
            round_span = (r0, loop.time())
            round_cpu = time.process_time() - c0
            worker_cpu = sum(cpu_seconds(p) for p in worker_pids) - w0
        # end half-way between ticks, at least `duration` after the warm-up
        first = min(p.tick_starts[0] for p in gw.pollers if p.tick_starts)
        end = max(wall0 + spec["duration"], loop.time())
        end = first + (math.floor((end - first) / period) + 0.5) * period
        await asyncio.sleep(max(0.0, end - loop.time()))
        cpu1, wall1 = time.process_time(), loop.time()
        await asyncio.sleep(0.45 * period)  # let polls started before `end` finish
        expected = stored = 0
        jit_all: list[float] = []
        jit_round: list[float] = []
        per_device = []
        for p in gw.pollers:
            t0, jit = _jitter(p.tick_starts, p.period)
            n_due = math.ceil((end - t0) / p.period) if jit else 0
            n_loops = sum(len(s.bank.loops) for s in p.groups)
            expected += n_due * n_loops
            for s in p.groups:
                b = s.bank
                rows = (b.t >= start_unix) & (b.t < end + off)
                stored += int(np.count_nonzero(b.quality[rows] == Quality.GOOD))
            jit_all += [j for t, j in jit if wall0 <= t < end]
            jit_round += [j for t, j in jit if round_span[0] <= t < round_span[1]]
            per_device.append({"name": p.device.name, "polls": p.polls,
                               "planned_requests": len(getattr(p.source, "requests", ())),
                               "min_requests": min_requests(
                                   [(pt.address.address, pt.address.width)
                                    for pt in p.source.points],  # type: ignore[attr-defined]
                                   p.device.options.max_registers_per_request),
                               "missed_ticks": p.missed_ticks})
        rss, hwm = rss_bytes()
        return {
            "loops": len(config.loops), "devices": len(config.devices), "period_s": period,
            "measured_s": wall1 - wall0, "cpu_s": cpu1 - cpu0,
            "jitter": jit_all, "jitter_round": jit_round,
            "expected": expected, "stored": stored, "devices_detail": per_device,
            "rss": rss, "hwm": hwm, "rss_start": rss_start, "rss_banks": rss_banks,
            "window_bytes": window_bytes, "samples_capacity": samples_capacity,
            "prefill_s": prefill_s, "round_s": round_span[1] - round_span[0],
            "round_cpu_s": round_cpu, "worker_cpu_s": worker_cpu,
            "loops_analysed": loops_analysed, "workers": gw.scheduler.workers,
            "run_s": loop.time() - t_begin,
        }


# ------------------------------------------------------------------------ parent


@dataclasses.dataclass
class ScaleResult:
    loops: int
    plcs: int
    duration_s: float
    requests_per_cycle: float  # measured at the PLCs
    planned_requests: int  # what the gateway planned per cycle
    min_requests: int  # the minimum the register layout allows
    cpu_percent: float  # gateway process, % of one core, over the measured time
    jitter_p50_ms: float
    jitter_p99_ms: float
    jitter_max_ms: float
    expected: int
    stored: int
    rss_mib: float
    hwm_mib: float
    bytes_per_sample: float  # window arrays / (loops x window samples)
    rss_bytes_per_sample: float  # RSS growth from building the windows, same divisor
    plc_cpu_percent: float  # all PLC processes together, % of one core
    plc_step_max_ms: float
    round_s: float = math.nan
    loops_analysed: int = 0
    round_cpu_percent: float = math.nan  # gateway process during the round
    worker_cpu_s: float = math.nan
    jitter_round_p50_ms: float = math.nan
    jitter_round_p99_ms: float = math.nan
    jitter_round_max_ms: float = math.nan
    workers: int = 0
    raw: dict[str, Any] = dataclasses.field(default_factory=dict, repr=False)

    @property
    def lost(self) -> int:
        return self.expected - self.stored


def _read_json_line(proc: subprocess.Popen[str], what: str) -> dict[str, Any]:
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line:
        raise RuntimeError(f"{what} exited early (status {proc.poll()})")
    return dict(json.loads(line))


def _child(args: list[str], log: Any, tree: Path | None = None) -> subprocess.Popen[str]:
    """``python -m bench.speed._scale ARGS``; with ``tree`` (a baseline's packages, see
    bench/attacks/_arena.py) its ``gateway``, ``plcsim`` and ``stiction`` are imported, not this
    repository's (only ``bench`` comes from here)."""
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    if tree is not None:
        env["PYTHONPATH"] = os.pathsep.join((str(tree), str(repo)))
    return subprocess.Popen([sys.executable, "-m", "bench.speed._scale", *args],
                            stdout=subprocess.PIPE, stderr=log, text=True, env=env,
                            cwd=tree or repo)


def run_scale(loops: int, *, plcs: int | None = None, duration: float = 60.0,
              warmup: float = 5.0, window_s: float = 3600.0, analysis: bool = False,
              workers: int = 0, tree: Path | None = None) -> ScaleResult:
    """Run M=``loops`` loops from ``plcs`` simulated PLCs for ``duration`` s (see module);
    ``tree``: run the PLCs and the gateway of that tree (a baseline's) instead of this
    repository's."""
    plcs = plcs or default_plcs(loops)
    procs: list[subprocess.Popen[str]] = []
    with tempfile.TemporaryDirectory(prefix="bench-scale-") as tmp:
        log = open(Path(tmp) / "children.log", "w+")  # noqa: SIM115 - closed below
        try:
            per = [loops // plcs + (1 if k < loops % plcs else 0) for k in range(plcs)]
            paths = []
            first = 0
            for k, n in enumerate(per):
                path = Path(tmp) / f"plc{k:02d}.yaml"
                path.write_text(yaml.safe_dump(sim_config(k, first, n, window_s=window_s)))
                paths.append(str(path))
                first += n
            sims = [_child(["sim", p], log, tree) for p in paths]
            procs += sims
            ports = [_read_json_line(p, "plc-sim")["port"] for p in sims]
            spec = {"sims": paths, "ports": ports, "duration": duration, "warmup": warmup,
                    "analysis": analysis, "workers": workers}
            spec_path = Path(tmp) / "gateway.json"
            spec_path.write_text(json.dumps(spec))
            gw = _child(["gateway", str(spec_path)], log, tree)
            procs.append(gw)
            res = _read_json_line(gw, "gateway")
            gw.wait(timeout=60)
            sim_stats = []
            for p in sims:
                p.send_signal(signal.SIGTERM)
            for p in sims:
                sim_stats.append(_read_json_line(p, "plc-sim"))
                p.wait(timeout=30)
        except BaseException:
            log.seek(0)
            tail = log.read()[-4000:]
            if tail:
                print(f"--- children's log (tail) ---\n{tail}", file=sys.stderr)
            raise
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
                    p.wait()
            log.close()
    dev = res["devices_detail"]
    req = sum(s["requests"] / max(1, d["polls"]) for s, d in zip(sim_stats, dev, strict=True))
    ms = 1e3
    cap = max(1, res["samples_capacity"])
    r = ScaleResult(
        loops=res["loops"], plcs=res["devices"], duration_s=res["measured_s"],
        requests_per_cycle=req,
        planned_requests=sum(d["planned_requests"] for d in dev),
        min_requests=sum(d["min_requests"] for d in dev),
        cpu_percent=100.0 * res["cpu_s"] / res["measured_s"],
        jitter_p50_ms=percentile(res["jitter"], 50) * ms,
        jitter_p99_ms=percentile(res["jitter"], 99) * ms,
        jitter_max_ms=max(res["jitter"], default=math.nan) * ms,
        expected=res["expected"], stored=res["stored"],
        rss_mib=res["rss"] / 2**20, hwm_mib=res["hwm"] / 2**20,
        bytes_per_sample=res["window_bytes"] / cap,
        rss_bytes_per_sample=(res["rss_banks"] - res["rss_start"]) / cap,
        plc_cpu_percent=100.0 * sum(s["cpu_s"] for s in sim_stats)
        / max(s["wall_s"] for s in sim_stats),
        plc_step_max_ms=max(s["step_max_s"] for s in sim_stats) * ms,
        workers=res["workers"], raw={"gateway": res, "plcs": sim_stats},
    )
    if analysis:
        r.round_s = res["round_s"]
        r.loops_analysed = res["loops_analysed"]
        r.round_cpu_percent = 100.0 * res["round_cpu_s"] / res["round_s"]
        r.worker_cpu_s = res["worker_cpu_s"]
        r.jitter_round_p50_ms = percentile(res["jitter_round"], 50) * ms
        r.jitter_round_p99_ms = percentile(res["jitter_round"], 99) * ms
        r.jitter_round_max_ms = max(res["jitter_round"], default=math.nan) * ms
    return r


def main(argv: Sequence[str]) -> int:
    """Child entry points: ``sim CONFIG`` and ``gateway SPEC``."""
    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    kind, path = argv
    if kind == "sim":
        asyncio.run(_sim_child(path))
        return 0
    if kind == "gateway":
        spec = json.loads(Path(path).read_text())
        out = asyncio.run(_gateway_child(spec))
        print(json.dumps(out), flush=True)
        return 0
    raise SystemExit(f"unknown child kind {kind!r}")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
