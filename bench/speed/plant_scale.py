"""Benchmark (issues 21 and 29): what the gateway's plant-wide step adds to a round.

A gateway of N loops on one poll interval (1 s), two-hour windows (the default
``window_s``): the loops are the project's simulated plants side by side
(:func:`stiction.scenarios.plants.plant_scenarios`, every kind in turn, so the gateway
holds sticky valves with followers, external cycles, cascades and quiet units). Each loop
carries a per-loop ``stiction`` suspicion (confidence 0.8), the worst case for the step.
Timed on one core, as a worker runs it: the windows copied out of the ring buffers and
averaged to ``plant.max_samples`` (:func:`gateway.core.plant.plant_jobs`, on the event loop
in the gateway), the job pickled and unpickled (the trip to the worker),
:func:`stiction.plant.analyze_plant` and :meth:`~stiction.plant.PlantAssessment.apply`.

Printed side by side for 1,000, 2,000, 5,000 and 10,000 loops, in one run: the step of the
baseline commit (``BENCH_BASELINE``, default :data:`BASELINE`: main when issue 37 was filed; its
packages extracted from git into a temporary folder and run in a subprocess on the same
windows) and of this tree, seconds and groups; and this tree's groups when the windows
hold lone missed polls (the polls of 20 devices of equal size, each missing one tick in a
hundred, at random: issue 29 saw 47 lone missed ticks in 210 s of 2,040 loops leave no group
for six rounds). Target: 10,000 loops in at most 30 s; with missed polls, the groups
formed without them. ``BENCH_QUICK=1`` stops at 2,000 loops.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.attacks._arena import baseline_tree
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
BASELINE = "5c94178"  # main when issues 35 and 37 were filed
DEVICES = 20
MISSED = 0.01  # share of each device's ticks missed, lone ones


def simulated(loops: int, seed: int = 0) -> tuple[list[str], np.ndarray, np.ndarray,
                                                   dict[str, str]]:
    """``loops`` simulated plant loops' two-hour windows: names, OP, PV (loops x samples,
    float32) and processes."""
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
            ops.append(rec.op[lp.name][-WINDOW_S:])
            pvs.append(rec.pv[lp.name][-WINDOW_S:])
            proc[name] = "integrating" if lp.integrating else "self-regulating"
    return (names[:loops], np.array(ops[:loops], np.float32), np.array(pvs[:loops], np.float32),
            proc)


def gateway_windows(names: list[str], op: np.ndarray, pv: np.ndarray, proc: dict[str, str],
                    missed: np.ndarray | None = None) -> LoopGroup:
    """One loop group of the windows; ``missed`` (loops x samples, True: the poll of that
    loop's device missed that tick) marks gaps."""
    bank = WindowBank(names, WINDOW_S)
    good = np.full(WINDOW_S, Quality.GOOD, dtype=np.uint8)
    load_columns(bank, np.arange(WINDOW_S, dtype=np.float64),
                 {c: (op[c], pv[c], good if missed is None else
                      np.where(missed[c], Quality.NO_COMM, Quality.GOOD).astype(np.uint8))
                  for c in range(len(names))})
    configs = tuple(LoopConfig(n, "plc", PointConfig(None), PointConfig(None), 0,
                               process=proc[n]) for n in names)
    cols = np.arange(len(names), dtype=np.intp)
    return LoopGroup("plc", bank, configs, cols, cols, cols, 1.0)


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


def missed_ticks(loops: int, seed: int = 1) -> np.ndarray:
    """Lone missed ticks: each of ``DEVICES`` devices (the loops split evenly) misses
    ``MISSED`` of its ticks, none two in a row."""
    rng = np.random.default_rng(seed)
    device = np.arange(loops) * DEVICES // loops
    ticks = rng.random((DEVICES, WINDOW_S)) < MISSED
    ticks[:, 1:] &= ~ticks[:, :-1]
    return np.asarray(ticks[device])


_CHILD = """
import pickle, sys, time, json
import numpy as np
sys.path.insert(0, sys.argv[1])
with open(sys.argv[2], "rb") as fh:
    names, op, pv, proc = pickle.load(fh)
from bench.speed.plant_scale import gateway_windows, time_step
from gateway.config import PlantSettings
seconds, groups, changed = time_step(gateway_windows(names, op, pv, proc), PlantSettings())
print(json.dumps([seconds, groups, changed]))
"""


def baseline_step(tree: Path, data: Path) -> tuple[float, int, int]:
    """The baseline's plant step on the same windows, in a subprocess (its packages first
    on the path; this bench's helpers build its loop group with its own classes)."""
    env = {**os.environ, "PYTHONPATH": f"{tree}{os.pathsep}{Path(__file__).parents[2]}",
           "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", _CHILD, str(tree), str(data)], env=env,
                         capture_output=True, text=True, check=True).stdout
    seconds, groups, changed = json.loads(out.strip().splitlines()[-1])
    return float(seconds), int(groups), int(changed)


def main() -> None:
    quick = bool(os.environ.get("BENCH_QUICK")) or "--quick" in sys.argv[1:]
    sizes = SIZES[:2] if quick else SIZES
    settings = PlantSettings()
    worst = last = 0.0
    with baseline_tree(os.environ.get("BENCH_BASELINE", BASELINE)) as (commit, tree), \
            tempfile.TemporaryDirectory() as tmp:
        print(f"\nplant-wide step of a round, one core ({WINDOW_S} s windows at 1 s, averaged "
              f"to {settings.max_samples} samples); before: {commit}, after: this tree")
        print(f"{'loops':>7} {'before s':>9} {'after s':>8} {'after s/1k':>11} "
              f"{'groups before':>14} {'after':>6} {'with missed polls':>18}")
        for n in sizes:
            names, op, pv, proc = simulated(n)
            data = Path(tmp) / "windows.pickle"
            data.write_bytes(pickle.dumps((names, op, pv, proc)))
            before, groups_before, _c = baseline_step(tree, data)
            seconds, groups, _changed = time_step(gateway_windows(names, op, pv, proc),
                                                  settings)
            _s, gapped, _c2 = time_step(gateway_windows(names, op, pv, proc, missed_ticks(n)),
                                        settings)
            print(f"{n:>7} {before:>9.1f} {seconds:>8.1f} {seconds / n * 1000:>11.2f} "
                  f"{groups_before:>14} {groups:>6} {gapped:>18}", flush=True)
            if n == SIZES[-1]:
                worst, last = seconds, before
    if not quick:
        verdict = "ok" if worst <= TARGET_S else "OVER"
        print(f"10,000 loops: {worst:.1f} s beside {last:.1f} s on {commit} (target <= "
              f"{TARGET_S:.0f} s): {verdict}")


if __name__ == "__main__":
    main()
