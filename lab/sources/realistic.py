"""The realistic generator (``stiction.scenarios.realistic``) as a source: the corpus's sets
(every cause, seeds 11-15, cached as plain dicts) and the simulated records that
``python -m bench real_data`` and the vote's calibration score (seeds 1-3: the two never
share a record)."""

from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from stiction.models.simulate import LoopBank
from stiction.scenarios import realistic  # the one import of the generator

from .. import _cache
from .._types import Window
from .records import Case

REALISTIC_SEEDS = (11, 12, 13, 14, 15)  # not SIM_SEEDS: no overlap with them
REALISTIC_CAUSES = realistic.CAUSES
REALISTIC_PER_CAUSE = 30  # records per cause and seed
REALISTIC_CLASS = {"stiction": "stiction", "tuning": "tuning", "disturbance": "disturbance",
                   "propagated": "propagated", "noise": "normal", "ramp-load": "ramp-load"}
SIM_SEEDS = (1, 2, 3)
AMBIGUOUS = ("ramp-load",)  # simulated causes scored apart, out of the totals


def _realistic_path(cache: Path, cause: str, seed: int) -> Path:
    src = inspect.getsource(realistic)
    key = hashlib.sha256(f"{src}{cause}{seed}{REALISTIC_PER_CAUSE}".encode()).hexdigest()
    return cache / f"realistic-{cause}-{seed}-{key[:12]}.pickle"


def build_realistic(cache: Path, log: Callable[[str], None]) -> int:
    """Draw what is not cached yet; returns how many (cause, seed) sets were drawn. Kept as
    plain dicts, so the cache does not depend on where the generator's classes live."""
    cache.mkdir(parents=True, exist_ok=True)
    done = 0
    for seed in REALISTIC_SEEDS:
        for cause in REALISTIC_CAUSES:
            path = _realistic_path(cache, cause, seed)
            if path.exists():
                continue
            recs = [{"cause": r.cause, "index": r.index, "ts": r.ts, "process": r.process,
                     "op": r.op, "pv": r.pv, "op_range": r.op_range, "fs": r.fs, "fd": r.fd,
                     "description": r.description, "sticky": r.sticky}
                    for r in realistic.realistic_loops(cause, REALISTIC_PER_CAUSE, seed=seed)]
            _cache.dump(recs, path)
            done += 1
            log(f"  realistic {cause} seed {seed}: {len(recs)} records")
    return done


def realistic_windows(cache: Path) -> list[Window]:
    out = []
    for seed in REALISTIC_SEEDS:
        for cause in REALISTIC_CAUSES:
            path = _realistic_path(cache, cause, seed)
            if not path.exists():
                continue
            recs: list[dict[str, Any]] = _cache.load(path)
            for r in recs:
                run = f"realistic-{cause}-{seed}-{r['index']}"
                out.append(Window(
                    "realistic", run, "loop", cause, REALISTIC_CLASS[cause], bool(r["sticky"]),
                    np.asarray(r["op"], dtype=np.float64), np.asarray(r["pv"], np.float64),
                    float(r["ts"]), r["process"], r["description"],
                    100.0 * float(r["fs"]), "record", float("nan"),
                    {"seed": seed, "index": r["index"], "fs": r["fs"], "fd": r["fd"],
                     "op_range": r["op_range"]}))
    return out


def sim_cases(per_seed: int) -> list[Case]:
    """``per_seed`` records of every cause for each of :data:`SIM_SEEDS` (cached in the lab's
    cache, keyed by the generator's source)."""
    src = inspect.getsource(realistic) + inspect.getsource(LoopBank) + \
        inspect.getsource(Case)
    key = hashlib.sha256(f"{src}{per_seed}{SIM_SEEDS}".encode()).hexdigest()[:16]
    path = _cache.root() / f"realistic-{key}.pickle"
    if path.exists():
        cached: list[Case] = _cache.load(path)
        return cached
    out = []
    for seed in SIM_SEEDS:
        for cause in realistic.CAUSES:
            for r in realistic.realistic_loops(cause, per_seed, seed=seed):
                out.append(Case("sim", f"{cause}-{seed}-{r.index}", f"{cause}-{seed}-{r.index}",
                                r.sticky, cause, r.op, r.pv, r.ts, r.process, r.description))
    _cache.dump(out, path)
    return out
