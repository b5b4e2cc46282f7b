"""Benchmark (issue 8, item 1): polling M = 100, 1,000, 10,000 loops at 1 s from N simulated
PLCs, each PLC and the gateway in its own process (see bench/speed/_scale.py for what is measured
and how).

Full run (the default, ``make bench``): 10,000 loops from 20 PLCs for 300 s, the smaller sizes
for 60 s. ``BENCH_QUICK=1`` (or ``python -m bench.speed.scale_polling --quick``) runs 20 s each;
``BENCH_SCALE_SECONDS=S`` sets every duration.

A second table checks that one simulated PLC can serve 10,000 loops in real time: the
vectorised step plus register encode, the cost of answering one 125-register read, and, for
comparison, updating the same 40,000 registers through pymodbus' ``async_setValues``; then
live: the gateway polls 10,000 loops from a single simulated PLC (60 s; 20 s quick).
"""

from __future__ import annotations

import asyncio
import math
import os
import statistics
import struct
import sys
import time

from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from bench.speed._scale import SCENARIO_MIX, ScaleResult, default_plcs, run_scale
from plcsim import PlcSim, parse_sim_config

SIZES = (100, 1000, 10000)
TARGET_CPU = 50.0  # % of one core
TARGET_P99_MS = 100.0


def durations(argv: list[str] | None = None) -> dict[int | str, float]:
    argv = sys.argv[1:] if argv is None else argv
    fixed = os.environ.get("BENCH_SCALE_SECONDS")
    if fixed:
        return dict.fromkeys((*SIZES, "one"), float(fixed))
    if "--quick" in argv or os.environ.get("BENCH_QUICK"):
        return dict.fromkeys((*SIZES, "one"), 20.0)
    return {100: 60.0, 1000: 60.0, 10000: 300.0, "one": 60.0}


def print_table(results: list[ScaleResult]) -> None:
    head = (f"{'loops':>6} {'PLCs':>4} {'secs':>5} {'req/cycle':>9} {'min':>5} "
            f"{'CPU %core':>9} {'jit p50 ms':>10} {'jit p99 ms':>10} {'jit max':>8} "
            f"{'expected':>9} {'stored':>9} {'lost':>5} {'RSS MiB':>8} {'PLCs CPU%':>9}")
    print(head)
    print(f"{'target':>6} {'':>4} {'':>5} {'= min':>9} {'':>5} {'< 50':>9} {'':>10} "
          f"{'< 100':>10} {'':>8} {'':>9} {'':>9} {'0':>5}")
    for r in results:
        print(f"{r.loops:>6} {r.plcs:>4} {r.duration_s:>5.0f} {r.requests_per_cycle:>9.1f} "
              f"{r.min_requests:>5} {r.cpu_percent:>9.1f} {r.jitter_p50_ms:>10.1f} "
              f"{r.jitter_p99_ms:>10.1f} {r.jitter_max_ms:>8.1f} {r.expected:>9} "
              f"{r.stored:>9} {r.lost:>5} {r.rss_mib:>8.0f} {r.plc_cpu_percent:>9.1f}")


def verdicts(r: ScaleResult) -> list[str]:
    def line(name: str, ok: bool, got: str, target: str) -> str:
        return f"  {'MET   ' if ok else 'MISSED'} {name}: {got} (target {target})"

    return [
        line("no sample lost", r.lost == 0, f"{r.lost} of {r.expected} lost", "0"),
        line("requests per cycle", math.isclose(r.requests_per_cycle, r.min_requests),
             f"{r.requests_per_cycle:.1f} measured at the PLCs, {r.planned_requests} planned",
             f"= {r.min_requests}"),
        line("polling CPU", r.cpu_percent < TARGET_CPU,
             f"{r.cpu_percent:.1f} % of one core ({r.cpu_percent / TARGET_CPU:.2f} x target)",
             f"< {TARGET_CPU:g} %"),
        line("poll jitter p99", r.jitter_p99_ms < TARGET_P99_MS,
             f"{r.jitter_p99_ms:.1f} ms ({r.jitter_p99_ms / TARGET_P99_MS:.2f} x target)",
             f"< {TARGET_P99_MS:g} ms"),
    ]


# ------------------------------------------------------------------------ PLC capacity


def plc_capacity(loops: int = 10000, repeats: int = 50) -> list[tuple[str, float, str]]:
    """(what, median ms, budget) for one simulated PLC serving ``loops`` loops."""
    return asyncio.run(_plc_capacity(loops, repeats))


async def _plc_capacity(loops: int, repeats: int) -> list[tuple[str, float, str]]:
    cfg = parse_sim_config({
        "listen": "127.0.0.1:0",
        "loops": [{"name": f"L{i}", "scenario": SCENARIO_MIX[i % len(SCENARIO_MIX)],
                   "noise": 0.05} for i in range(loops)]})
    sim = PlcSim(cfg)  # not started: step() and the read hook are called directly
    for _ in range(5):
        sim.step()
    step = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.step()
        step.append(time.perf_counter() - t0)

    regs = len(sim.image)
    n_reads = math.ceil(regs / 125)
    pdus = [struct.pack(">BHH", 3, k * 125, min(125, regs - k * 125)) for k in range(n_reads)]
    reads = []
    for _ in range(5):
        t0 = time.perf_counter()
        for pdu in pdus:
            sim.server.answer(sim.server.unit_id, pdu)
        reads.append((time.perf_counter() - t0) / n_reads)

    dev = SimDevice(id=1, simdata=[SimData(0, count=regs, datatype=DataType.REGISTERS)])
    server = ModbusTcpServer([dev], address=("127.0.0.1", 0))
    setv = []
    for _ in range(max(3, repeats // 5)):
        t0 = time.perf_counter()
        await server.async_setValues(1, 3, 0, sim.image.tolist())
        setv.append(time.perf_counter() - t0)
    return [
        (f"step + encode {loops} loops (vectorised, numpy image)",
         statistics.median(step) * 1e3, f"1000 (Ts); max {max(step) * 1e3:.1f}"),
        (f"answer one 125-register read (x {n_reads} per poll)",
         statistics.median(reads) * 1e3, f"{1000 / n_reads:.1f} each"),
        (f"pymodbus async_setValues of all {regs} registers (not used)",
         statistics.median(setv) * 1e3, "1000"),
    ]


def main() -> None:
    dur = durations()
    print(f"== scale_polling: M loops at 1 s from N simulated PLCs, separate processes "
          f"(cores: {os.cpu_count()}) ==")
    results = []
    for m in SIZES:
        r = run_scale(m, plcs=default_plcs(m), duration=dur[m])
        results.append(r)
    print_table(results)
    big = results[-1]
    one = run_scale(10000, plcs=1, duration=dur["one"])
    print(f"targets at {big.loops} loops from {big.plcs} PLCs over {big.duration_s:.0f} s:")
    for line in verdicts(big):
        print(line)
    print("(CPU: gateway process time / wall time, its threads included, analysis workers "
          "idle; jitter: poll start minus due time; RSS: gateway process, 3,600-sample "
          "windows)")
    print()
    print(f"== scale_polling: one simulated PLC serving 10,000 loops (cores: {os.cpu_count()}) ==")
    print(f"{'what':<62} {'median ms':>10} {'budget ms':>24}")
    for what, ms, budget in plc_capacity():
        print(f"{what:<62} {ms:>10.3f} {budget:>24}")
    print(f"(PLC processes' CPU in the {big.loops}-loop run: {big.plc_cpu_percent:.1f} % of one "
          f"core for {big.plcs} PLCs; slowest step {big.plc_step_max_ms:.1f} ms)")
    print(f"live: {one.loops} loops from ONE simulated PLC for {one.duration_s:.0f} s:")
    print_table([one])
    print(f"(that PLC: {one.plc_cpu_percent:.1f} % of one core, slowest step "
          f"{one.plc_step_max_ms:.1f} ms, {one.requests_per_cycle:.0f} reads per poll)")
    print()


if __name__ == "__main__":
    main()
