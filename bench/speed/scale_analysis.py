"""Benchmark (issue 8, item 2; issue 28, item 5): analysis throughput, this tree beside the
baseline (main when issue 28 was filed; ``BENCH_BASELINE`` for another commit) in one run.

Windows are simulated with stiction's LoopBank, loop i running scenario
``SCENARIO_MIX[i % 10]`` (7 of 10 sticky: a pessimistic plant), 0.05 PV noise, Ts 1 s.

1. Per window, one process: the CPU time of what a worker does for one loop
   (:func:`gateway.core.jobs.analyze_batch`: window fill, gap handling, ``analyze``) for
   1 h, 2 h and 4 h windows, before and after, interleaved job by job (the baseline's
   ``stiction`` imported beside this tree's, bench/_baseline.py): median, p90, sticky and
   other medians, and the mean as the round of 10,000 such windows on one core.
2. With the gateway's worker pool (:class:`gateway.runtime.scheduler.AnalysisScheduler`, default
   workers = cores - 1): loops analysed per second for a bank of K loops per window length
   (this tree).
3. End to end: one full analysis round of 10,000 two-hour windows inside a gateway that
   keeps polling 10,000 loops from 20 simulated PLCs (separate processes, bench/speed/_scale.py),
   with the poll jitter of the ticks during the round: the baseline's gateway, then this
   tree's (target: the round at most 120 s on one core, issue 28).

``BENCH_QUICK=1`` (or ``--quick``) uses fewer loops in 1 and 2; the end-to-end round is
always 10,000 loops (set ``BENCH_SCALE_ROUND_LOOPS`` to change it) with the gateway's
default worker count (``BENCH_SCALE_WORKERS`` sets another).
"""

from __future__ import annotations

import asyncio
import os
import sys
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from bench._baseline import ALIAS, BASELINE, baseline_stiction
from bench.attacks._arena import baseline_tree
from bench.speed._scale import SCENARIO_MIX, ScaleResult, percentile, run_scale
from gateway.config import LoopConfig, PointConfig
from gateway.core.jobs import LoopJob, analyze_batch
from gateway.core.points import Quality
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup, WindowBank
from gateway.runtime.scheduler import AnalysisScheduler
from plcsim import parse_sim_config
from plcsim.sim import build_banks
from stiction.scenarios import SCENARIOS

WINDOWS_S = (3600, 7200, 14400)
TARGET_MEDIAN_MS = 5.0  # for 3600 samples
TARGET_ROUND_S = 120.0  # issue 28: a round of 10,000 two-hour windows on one core
TARGET_P99_MS = 100.0


def quick(argv: list[str] | None = None) -> bool:
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or bool(os.environ.get("BENCH_QUICK"))


def simulate_windows(loops: int, samples: int, seed: int = 0
                     ) -> tuple[NDArray[np.float32], NDArray[np.float32], list[str]]:
    """(samples, loops) OP and PV of the scenario mix, and each loop's scenario name."""
    cfg = parse_sim_config({
        "listen": "127.0.0.1:0", "seed": seed,
        "loops": [{"name": f"L{i}", "scenario": SCENARIO_MIX[i % len(SCENARIO_MIX)],
                   "noise": 0.05} for i in range(loops)]})
    op = np.empty((samples, loops), dtype=np.float32)
    pv = np.empty((samples, loops), dtype=np.float32)
    banks = build_banks(cfg)
    for k in range(samples):
        for b in banks:
            out = b.bank.step(b.sp_base + np.where(b.bank.t >= b.sp_time, b.sp_step, 0.0))
            op[k, b.rows] = out.op
            pv[k, b.rows] = out.pv
    return op, pv, [lp.scenario.name for lp in cfg.loops]


def loop_config(i: int, name: str, window_s: float) -> LoopConfig:
    sc = SCENARIOS[name]
    return LoopConfig(name=f"L{i}", device="sim", op=PointConfig(None), pv=PointConfig(None),
                      result_address=0, kp=sc.kp, delay_s=sc.theta, window_s=window_s,
                      process="integrating" if sc.integrating else "self-regulating")


def jobs_for(op: NDArray[np.float32], pv: NDArray[np.float32], names: list[str],
             samples: int) -> list[LoopJob]:
    q = np.full(samples, Quality.GOOD, dtype=np.uint8)
    out = []
    for i, name in enumerate(names):
        cfg = loop_config(i, name, samples)
        out.append(LoopJob(i, op[-samples:, i].copy(), pv[-samples:, i].copy(), q, samples,
                           1.0, cfg.kp, cfg.delay_s, cfg.process, cfg.op_range))
    return out


def _cpu_per_job(path: str, jobs: list[LoopJob]) -> list[float]:
    """CPU seconds of :func:`analyze_batch` on each job alone."""
    out = []
    for job in jobs:
        t0 = time.process_time()
        analyze_batch(path, [job])
        out.append(time.process_time() - t0)
    return out


def per_window(op: NDArray[np.float32], pv: NDArray[np.float32], names: list[str],
               paths: dict[str, str]) -> None:
    """Per-window CPU time of each version (``paths``: version -> analysis function)."""
    print(f"== scale_analysis: CPU time per window, one process, before and after "
          f"(cores: {os.cpu_count()}) ==")
    print(f"{'window':>7} {'loops':>5} {'version':>7} {'median ms':>9} {'p90 ms':>7} "
          f"{'sticky med':>10} {'other med':>9} {'mean ms':>7} {'10k loops s':>11} "
          f"{'target s':>8}")
    sticky = np.array([SCENARIOS[n].sticky for n in names])
    for w in WINDOWS_S:
        jobs = jobs_for(op, pv, names, w)
        for path in paths.values():
            analyze_batch(path, jobs[:10])  # warm up
        times: dict[str, list[list[float]]] = {v: [] for v in paths}
        for k in range(3):  # three passes, the versions in turn; the median per loop
            for v in (list(paths) if k % 2 == 0 else list(paths)[::-1]):
                times[v].append(_cpu_per_job(paths[v], jobs))
        for v in paths:
            t = np.median(np.array(times[v]), axis=0)
            target = f"{TARGET_ROUND_S:g}" if w == 7200 else ""
            print(f"{w // 3600:>6}h {len(jobs):>5} {v:>7} {np.median(t) * 1e3:>9.2f} "
                  f"{np.percentile(t, 90) * 1e3:>7.2f} {np.median(t[sticky]) * 1e3:>10.2f} "
                  f"{np.median(t[~sticky]) * 1e3:>9.2f} {t.mean() * 1e3:>7.2f} "
                  f"{t.mean() * 1e4:>11.0f} {target:>8}")
    print(f"(mix: {', '.join(SCENARIO_MIX)}, round robin; 'sticky' = the 7 scenarios with "
          "fs > 0; '10k loops s': 10,000 x the mean, a round of such windows on one core "
          "with nothing else on it)")
    print()


async def _pool_round(op: NDArray[np.float32], pv: NDArray[np.float32], names: list[str],
                      samples: int, *, loops: int, workers: int
                      ) -> tuple[float, int, int]:
    n = len(names)
    bank = WindowBank([f"L{i}" for i in range(loops)], samples)
    cols = np.arange(loops) % n
    bank.op[:] = op[-samples:, cols]
    bank.pv[:] = pv[-samples:, cols]
    bank.quality[:] = Quality.GOOD
    bank.t[:] = np.arange(samples, dtype=np.float64)
    bank.count = samples
    configs = [loop_config(i, names[i % n], samples) for i in range(loops)]
    store = ResultStore([c.name for c in configs])
    ks = np.arange(loops, dtype=np.intp)
    group = LoopGroup("bench", bank, tuple(configs), 2 * ks, 2 * ks + 1, ks, 1.0)
    sched = AnalysisScheduler([group], store, interval_wall_s=1e9, workers=workers)
    await sched.start()
    try:
        t0 = time.perf_counter()
        done = await sched.run_round()
        return time.perf_counter() - t0, done, sched.workers
    finally:
        await sched.stop()


def pool_throughput(op: NDArray[np.float32], pv: NDArray[np.float32], names: list[str],
                    loops: int) -> None:
    cores = os.cpu_count() or 1
    print(f"== scale_analysis: worker pool throughput, {loops} loops per round "
          f"(cores: {cores}) ==")
    print(f"{'window':>7} {'workers':>7} {'round s':>8} {'loops/s':>8} "
          f"{'10k loops s':>11} {'target s':>8}")
    for w in WINDOWS_S:
        for workers in sorted({max(1, cores - 1), cores}):
            secs, done, nw = asyncio.run(_pool_round(op, pv, names, w, loops=loops,
                                                              workers=workers))
            rate = done / secs
            target = f"{TARGET_ROUND_S:g}" if w == 7200 else ""
            default = " (default)" if workers == max(1, cores - 1) else ""
            print(f"{w // 3600:>6}h {nw:>7} {secs:>8.1f} {rate:>8.0f} {10000 / rate:>11.0f} "
                  f"{target:>8}{default}")
    print("(10k loops s: 10,000 / loops per second, the time a round of 10,000 such windows "
          "would take)")
    print()


def end_to_end(loops: int, workers: int = 0) -> None:
    """The round in a polling gateway: the baseline's, then this tree's."""
    print(f"== scale_analysis: one analysis round of {loops} two-hour windows while polling "
          f"{loops} loops from 20 PLCs, before and after (cores: {os.cpu_count()}) ==")
    runs = {}
    with baseline_tree(os.environ.get("BENCH_BASELINE", BASELINE)) as (commit, tree):
        for version, where in (("before", tree), ("after", None)):
            runs[version] = run_scale(loops, plcs=20, duration=30.0, warmup=5.0,
                                      window_s=7200.0, analysis=True, workers=workers,
                                      tree=where)
    b, a = runs["before"], runs["after"]
    print(f"before: main at {commit} (git archive); after: this tree")
    print(f"{'what':<46} {'before':>12} {'after':>12} {'target':>10}")
    rows: list[tuple[str, Callable[[ScaleResult], str], str]] = [
        ("loops analysed in the round", lambda r: f"{r.loops_analysed}", f"{loops}"),
        ("round wall time, s", lambda r: f"{r.round_s:.1f}", f"< {TARGET_ROUND_S:g}"),
        ("round / target", lambda r: f"{r.round_s / TARGET_ROUND_S:.2f} x", "<= 1"),
        ("loops analysed per second", lambda r: f"{r.loops_analysed / r.round_s:.0f}", ""),
        ("analysis workers", lambda r: f"{r.workers}", ""),
        ("worker CPU during the round, s", lambda r: f"{r.worker_cpu_s:.1f}", ""),
        ("round if workers had their cores to themselves, s",
         lambda r: f"{r.worker_cpu_s / r.workers:.1f}", f"< {TARGET_ROUND_S:g}"),
        ("gateway process CPU during the round, % core",
         lambda r: f"{r.round_cpu_percent:.1f}", ""),
        ("poll ticks during the round", lambda r: f"{len(r.raw['gateway']['jitter_round'])}",
         ""),
        ("poll jitter during the round p50, ms", lambda r: f"{r.jitter_round_p50_ms:.1f}", ""),
        ("poll jitter during the round p99, ms", lambda r: f"{r.jitter_round_p99_ms:.1f}",
         f"< {TARGET_P99_MS:g}"),
        ("poll jitter during the round max, ms", lambda r: f"{r.jitter_round_max_ms:.1f}", ""),
        ("poll jitter whole run p99, ms", lambda r: f"{r.jitter_p99_ms:.1f}",
         f"< {TARGET_P99_MS:g}"),
        ("samples expected / stored (whole run)", lambda r: f"{r.expected}/{r.stored}",
         "equal"),
        ("requests per cycle / minimum",
         lambda r: f"{r.requests_per_cycle:.1f}/{r.min_requests}", "equal"),
        ("gateway RSS / peak, MiB", lambda r: f"{r.rss_mib:.0f}/{r.hwm_mib:.0f}", ""),
    ]
    for what, fmt, target in rows:
        print(f"{what:<46} {fmt(b):>12} {fmt(a):>12} {target:>10}")
    for v, r in runs.items():
        jr = r.raw["gateway"]["jitter_round"]
        print(f"({v}: windows pre-filled with 7200 simulated samples per loop, "
              f"{r.raw['gateway']['prefill_s']:.0f} s; p50/p99 of {len(jr)} ticks: "
              f"{percentile(jr, 50) * 1e3:.1f}/{percentile(jr, 99) * 1e3:.1f} ms)")
    print(f"(the round x{b.round_s / a.round_s:.2f} faster, the workers' CPU "
          f"x{b.worker_cpu_s / a.worker_cpu_s:.2f} less)")
    print()


def main() -> None:
    q = quick()
    sample_loops = 50 if q else 200
    op, pv, names = simulate_windows(sample_loops, max(WINDOWS_S))
    with baseline_stiction():
        per_window(op, pv, names, {"before": f"{ALIAS}:analyze", "after": "stiction:analyze"})
    pool_throughput(op, pv, names, 200 if q else 1000)
    end_to_end(int(os.environ.get("BENCH_SCALE_ROUND_LOOPS", "10000")),
               int(os.environ.get("BENCH_SCALE_WORKERS", "0")))


if __name__ == "__main__":
    main()
