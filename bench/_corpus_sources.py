"""The development corpus's other sources: ``stiction.scenarios.realistic`` (every cause, several
seeds, cached), the plant records and the shared TEP runs (bench/real_data.py's loaders)
and the single cases of ../shared/data/cases."""

from __future__ import annotations

import collections
import csv
import hashlib
import inspect
import pickle
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from stiction.scenarios import realistic  # the one import of the generator

from . import real_data
from ._corpus_types import PlantRun, Window

REALISTIC_SEEDS = (11, 12, 13, 14, 15)  # not bench/real_data.py's 1-3: no overlap with it
REALISTIC_CAUSES = realistic.CAUSES
REALISTIC_PER_CAUSE = 30  # records per cause and seed
REALISTIC_CLASS = {"stiction": "stiction", "tuning": "tuning", "disturbance": "disturbance",
                   "propagated": "propagated", "noise": "normal", "ramp-load": "ramp-load"}
CASES = real_data.SHARED / "cases"
# the cases' README gives what went wrong and the right answer; each known file here
CASE_LABELS = {"aggressive-tuning-analyze-raises": ("tuning", "tuning", "self-regulating")}


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
            tmp = path.with_suffix(".tmp")
            with tmp.open("wb") as fh:
                pickle.dump(recs, fh, protocol=pickle.HIGHEST_PROTOCOL)
            tmp.replace(path)
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
            with path.open("rb") as fh:
                recs: list[dict[str, Any]] = pickle.load(fh)
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


def plant_windows() -> list[Window]:
    """The plant records, one run per tag (records of a tag are one valve)."""
    with (real_data.PLANT / "labels.csv").open() as fh:
        types = {r["loop"]: r["loop_type"] for r in csv.DictReader(fh)}
    out = []
    for c in real_data.plant_cases():
        kind = types[c.name]
        process = "integrating" if kind == "level" else "self-regulating"
        out.append(Window(
            "plant", f"plant-{c.group}", c.name, kind,
            "stiction" if c.sticky else "non-stiction", c.sticky, c.op, c.pv, c.ts, process,
            f"{kind} loop, tag {c.group}; label as published (how it was assigned is not "
            "documented); process type from the loop type (level: integrating)",
            float("nan"), "record", float("nan"), {"tag": c.group, "loop_type": kind}))
    return out


def _shared_run(name: str) -> tuple[str, str, int | None]:
    """(run, loop, IDV) of a shared TEP record: ``braatz/d14_te_reactor_cw`` is loop
    ``reactor_cw`` of run ``braatz/d14_te``, IDV 14."""
    sub, base = name.split("/", 1)
    m = re.match(r"(d(\d\d)(?:_te)?|idv(\d\d))_(.+)$", base)
    if m is None:
        return name, "loop", None
    idv = int(m.group(2) or m.group(3))
    return f"{sub}/{m.group(1)}", m.group(4), idv or None


def shared_tep_windows() -> list[Window]:
    out = []
    for c in real_data.tep_cases():
        run, loop, idv = _shared_run(c.name)
        cls = {"normal": "normal", "propagated": "propagated", "disturbance": "disturbance"}
        cause_class = "stiction" if c.sticky else cls.get(c.cause, "disturbance")
        cause = f"idv{idv}" if idv else "normal"
        hidden = "; README: IDV 15 is barely visible in these records" if idv == 15 else ""
        out.append(Window(
            "tep-shared", f"tep-shared-{run}", loop, cause, cause_class, c.sticky, c.op, c.pv,
            c.ts, "self-regulating", f"{c.name}: {c.cause}{hidden}", float("nan"), "record",
            float("nan"), {"idv": idv}))
    return out


def shared_tep_plant_runs(windows: list[Window]) -> list[PlantRun]:
    """The shared TEP runs as plant runs: two loops each (the two cooling-water valves'),
    no other signal recorded."""
    by_run: dict[str, list[Window]] = collections.defaultdict(list)
    for w in windows:
        by_run[w.run].append(w)
    out = []
    for run, ws in sorted(by_run.items()):
        n = min(w.op.size for w in ws)
        idv = ws[0].meta["idv"]
        sticky = tuple(w.loop for w in ws if w.sticky)
        out.append(PlantRun(
            run, "tep-shared", "mode1", None, ((idv, 1.0),) if idv else (), {},
            ws[0].ts, {w.loop: (w.op[:n], w.pv[:n]) for w in ws}, {}, {},
            {w.loop: w.cause_class for w in ws}, sticky,
            bool(idv) and idv not in (14, 15), "; ".join(sorted({w.note for w in ws}))))
    return out


def case_windows() -> list[Window]:
    """The single cases whose right answer the README gives (others are left out)."""
    out = []
    for path in sorted(CASES.glob("*.csv")):
        if path.stem not in CASE_LABELS:
            continue
        cause, cause_class, process = CASE_LABELS[path.stem]
        d = np.genfromtxt(path, delimiter=",", names=True)
        ts = float(np.median(np.diff(d["t"])))
        out.append(Window(
            "cases", f"case-{path.stem}", "loop", cause, cause_class, False,
            np.asarray(d["op"], np.float64), np.asarray(d["pv"], np.float64), ts, process,
            "README: a healthy valve, PI tuned far too aggressively; the right answer is a "
            "verdict and not stiction", 0.0, "record", float("nan"), {}))
    return out
