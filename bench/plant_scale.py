"""Benchmark (issue 21, item 3): what the gateway's plant-wide step adds to a round.

A gateway of N loops on one poll interval (1 s), two-hour windows (the default
``window_s``): the loops are the project's simulated plants side by side
(:func:`stiction.scenarios.plants.plant_scenarios`, every kind in turn, so the gateway
holds sticky valves with followers, external cycles, cascades and quiet units). Each loop
carries a per-loop ``stiction`` suspicion (confidence 0.8), the worst case for the step.
Timed on one core, in this process, as a worker runs it: the windows copied out of the
ring buffers and averaged to ``plant.max_samples`` (:func:`gateway.core.plant.plant_jobs`,
on the event loop in the gateway), the job pickled and unpickled (the trip to the worker),
:func:`stiction.plant.analyze_plant` and :meth:`~stiction.plant.PlantAssessment.apply`.

Printed side by side for 1,000, 2,000, 5,000 and 10,000 loops: seconds, seconds per 1,000
loops (flat when the cost grows linearly) and groups found. Target: 10,000 loops in at most
30 s. ``BENCH_QUICK=1`` stops at 2,000 loops.
"""

from __future__ import annotations

import os
import pickle
import sys
import time

import numpy as np

from gateway.config import LoopConfig, PlantSettings, PointConfig
from gateway.core.plant import analyze_plant_job, plant_jobs
from gateway.core.points import Quality
from gateway.core.windows import LoopGroup, WindowBank, load_columns
from stiction import Assessment, Verdict
from stiction.scenarios.plant import simulate_plants
from stiction.scenarios.plants import PLANT_KINDS, plant_scenarios

SIZES = (1000, 2000, 5000, 10000)
WINDOW_S = 7200
TARGET_S = 30.0


def gateway_windows(loops: int, seed: int = 0) -> tuple[LoopGroup, dict[str, str]]:
    """One device's loop group of ``loops`` simulated plant loops, windows full."""
    scenarios = []
    k = 0
    while sum(len(sc.loops) for sc in scenarios) < loops:
        kind = PLANT_KINDS[k % len(PLANT_KINDS)]
        scenarios.extend(plant_scenarios(kind, 1, seed=seed * 100_000 + k))
        k += 1
    recs = simulate_plants(scenarios, duration=float(WINDOW_S), warmup=900.0, seed=seed)
    names, ops, pvs, proc = [], [], [], {}
    for p, rec in enumerate(recs):
        for lp in rec.scenario.loops:
            name = f"P{p}.{lp.name}"
            names.append(name)
            ops.append(rec.op[lp.name])
            pvs.append(rec.pv[lp.name])
            proc[name] = "integrating" if lp.integrating else "self-regulating"
    names = names[:loops]
    bank = WindowBank(names, WINDOW_S)
    q = np.full(WINDOW_S, Quality.GOOD, dtype=np.uint8)
    load_columns(bank, np.arange(WINDOW_S, dtype=np.float64),
                 {c: (ops[c][-WINDOW_S:].astype(np.float32),
                      pvs[c][-WINDOW_S:].astype(np.float32), q) for c in range(loops)})
    configs = tuple(LoopConfig(n, "plc", PointConfig(None), PointConfig(None), 0,
                               process=proc[n]) for n in names)
    cols = np.arange(loops, dtype=np.intp)
    return LoopGroup("plc", bank, configs, cols, cols, cols, 1.0), proc


def time_step(group: LoopGroup, settings: PlantSettings) -> tuple[float, int, int]:
    """(seconds, groups, loops turned propagated) of one plant step over ``group``."""
    suspect = Assessment(Verdict.STICTION, "suspected", oscillating=True, confidence=0.8)
    assessments = dict.fromkeys(range(len(group.configs)), suspect)
    t0 = time.perf_counter()
    (job,) = plant_jobs([group], assessments, max_samples=settings.max_samples)
    job = pickle.loads(pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL))
    pa = analyze_plant_job(job)
    after = pa.apply(job.assessments)
    seconds = time.perf_counter() - t0
    changed = sum(1 for n in job.names if after[n] is not job.assessments[n])
    return seconds, len(pa.groups), changed


def main() -> None:
    quick = bool(os.environ.get("BENCH_QUICK")) or "--quick" in sys.argv[1:]
    sizes = SIZES[:2] if quick else SIZES
    settings = PlantSettings()
    print(f"\nplant-wide step of a round, one core ({WINDOW_S} s windows at 1 s, averaged to "
          f"{settings.max_samples} samples)")
    print(f"{'loops':>7} {'seconds':>8} {'s / 1k loops':>13} {'groups':>7} {'propagated':>11}")
    worst = 0.0
    for n in sizes:
        group, _proc = gateway_windows(n)
        seconds, groups, changed = time_step(group, settings)
        print(f"{n:>7} {seconds:>8.1f} {seconds / n * 1000:>13.2f} {groups:>7} {changed:>11}",
              flush=True)
        if n == SIZES[-1]:
            worst = seconds
    if not quick:
        verdict = "ok" if worst <= TARGET_S else "OVER"
        print(f"10,000 loops: {worst:.1f} s (target <= {TARGET_S:.0f} s): {verdict}")


if __name__ == "__main__":
    main()
