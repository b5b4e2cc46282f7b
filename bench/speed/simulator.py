"""Benchmark: time to step 10,000 simulated loops one sample (the simulated PLC's budget).

Baseline beside it: the same loops stepped one at a time in a Python loop (on a subset,
scaled), so the table shows what vectorisation buys on this machine.
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np

from stiction.models.simulate import LoopBank, LoopParams
from stiction.models.valves import HeValve
from stiction.scenarios import scenario


def _bank(n: int) -> LoopBank:
    sc = scenario("table6")
    rng = np.random.default_rng(0)
    params = LoopParams(kc=sc.kc, ti=sc.ti, kp=1.0, tau=rng.uniform(60, 480, n),
                        theta=rng.uniform(0, 20, n), noise_sd=0.1)
    fs = rng.uniform(0.0, 0.3, n)
    return LoopBank(n, params, HeValve(fs, fs * 0.9, 1.99), seed=1)


def time_steps(bank: LoopBank, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        bank.step()
        times.append(time.perf_counter() - t0)
    return times


def main() -> None:
    print(f"== simulator: one sample of N loops (cores: {os.cpu_count()}) ==")
    head = f"{'loops':>8} {'vectorised median ms':>22} {'per-loop Python ms (est.)':>27}"
    print(f"{head} {'ratio':>7}")
    for n in (100, 1000, 10000):
        bank = _bank(n)
        time_steps(bank, 20)  # warm up
        vec = statistics.median(time_steps(bank, 200))
        singles = [_bank(1) for _ in range(50)]
        per_loop = statistics.median(
            sum(time_steps(b, 1)[0] for b in singles) for _ in range(20)
        ) / len(singles)
        base = per_loop * n
        print(f"{n:>8} {vec * 1e3:>22.3f} {base * 1e3:>27.1f} {base / vec:>6.0f}x")
    print()


if __name__ == "__main__":
    main()
