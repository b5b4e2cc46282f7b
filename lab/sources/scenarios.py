"""The named closed loops (stiction.scenarios.named) drawn around the paper's cases, as one
more source for the decision's fit: clean and noisy limit cycles of a sticky valve in fast,
slow and level loops, and good valves under tuning, a periodic load and random loads.

Each record: a base scenario, parameters drawn around it (a sticky valve's fs 3-35 % and fd
50-95 % of fs; the slow loop's time constant 60-480 s and dead time 2-35 s), PV noise 0.02,
0.1 or 0.3, a random load in half of them; the window after the start-up transient, at 1 s
and (slow loops) 5 s. A sticky record is kept when its valve slips at least 6 times in the
window. Drawn from ``numpy.random.default_rng((SEED, i))``; cached.
"""

from __future__ import annotations

import hashlib
import inspect
from pathlib import Path

import numpy as np

from stiction.scenarios import named
from stiction.scenarios.named import scenario, simulate

from .. import _cache
from .._types import Window

SEED = 24
COUNT = 240  # records drawn (sticky and good alternately)
STICKY = ("table4-case2", "table5-case2", "table6", "table7")
GOOD = ("healthy", "aggressive-tuning", "disturbance")
CLASS = {"healthy": "normal", "aggressive-tuning": "tuning", "disturbance": "disturbance"}


def _draw(i: int) -> tuple[str, dict[str, float], float, float, int]:
    rng = np.random.default_rng((SEED, i))
    noise = float(rng.choice([0.02, 0.1, 0.3]))
    load = float(rng.choice([0.0, 0.003])) if rng.random() < 0.5 else 0.0
    if i % 2 == 0:
        name = str(rng.choice(STICKY))
        fs = float(rng.uniform(0.03, 0.35))
        over: dict[str, float] = {"fs": fs, "fd": fs * float(rng.uniform(0.5, 0.95))}
        if name in ("table6", "table7"):
            over["tau"] = float(rng.uniform(60.0, 480.0))
            over["theta"] = float(rng.uniform(2.0, 35.0))
    else:
        name = str(rng.choice(GOOD))
        over = {}
        if name == "disturbance":
            over["dist_period"] = float(rng.uniform(200.0, 1500.0))
            over["dist_amp"] = float(rng.uniform(0.01, 0.05))
    if load:
        over["load_sd"] = load
    step = int(rng.choice([1, 5])) if name in ("table6", "table7", "healthy", "disturbance") \
        else 1
    return name, over, noise, load, step


def _slips(vp: np.ndarray) -> int:
    moving = np.abs(np.diff(vp)) > 1e-9
    return int(np.count_nonzero(moving[1:] & ~moving[:-1]))


def windows(cache: Path) -> list[Window]:
    src = inspect.getsource(named) + inspect.getsource(_draw)
    key = hashlib.sha256(f"{src}{SEED}{COUNT}".encode()).hexdigest()[:12]
    path = cache / f"train-scenarios-{key}.pickle"
    if path.exists():
        cached: list[Window] = _cache.load(path)
        return cached
    out = []
    for i in range(COUNT):
        name, over, noise, _load, step = _draw(i)
        sc = scenario(name, **over)
        res = simulate(sc, noise=noise, seed=i)
        start = min(res.t.size // 3, 1800)
        sl = slice(start, None, step)
        sticky = sc.sticky and _slips(res.vp[sl]) >= 6
        if sc.sticky and not sticky:
            continue
        cls = "stiction" if sticky else CLASS[name]
        process = "integrating" if sc.integrating else "self-regulating"
        out.append(Window("scenarios", f"scenario-{i}", name, name, cls, sticky,
                          np.asarray(res.op[sl]), np.asarray(res.pv[sl]), float(step) * sc.ts,
                          process, f"{name} {over} noise {noise}", 100.0 * sc.fs, "record"))
    _cache.dump(out, path)
    return out
