"""The plant-wide benchmark's data: the project's plants at the gateway's sampling and
resampled as a historian exports them, each loop analysed; the TEP plant runs. Cached in
bench/.cache by the generators' and the analysis' source."""

from __future__ import annotations

import hashlib
import inspect
import os
import pickle
from pathlib import Path
from typing import Any

import numpy as np

import stiction
from stiction import Assessment, analyze
from stiction.scenarios import plant as plant_module
from stiction.scenarios import plants as plants_module
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import plant_scenarios

CACHE = Path(__file__).resolve().parent / ".cache"
DURATION, SAMPLE = 14400.0, 4
VIEWS = (4.0, 10.0, 20.0, 60.0)
"""Sample times of the views, s: the gateway's (the simulation kept every 4 s) and a
historian's interpolated exports at 10, 20 and 60 s."""

Analysed = list[tuple[PlantRecord, dict[str, Assessment]]]


def processes(rec: PlantRecord) -> dict[str, str]:
    return {lp.name: "integrating" if lp.integrating else "self-regulating"
            for lp in rec.scenario.loops}


def cascades(rec: PlantRecord) -> dict[str, str]:
    return {ln.source: ln.target for ln in rec.scenario.links if ln.kind == "setpoint"}


def _pickled(path: Path, make: Any) -> Any:
    if path.exists():
        with path.open("rb") as fh:
            return pickle.load(fh)
    out = make()
    CACHE.mkdir(exist_ok=True)
    with path.open("wb") as fh:
        pickle.dump(out, fh)
    return out


def _code_key() -> str:
    """The per-loop analysis' code: stiction/ without the plant view and the CLI (a change
    to the plant view analyses nothing again)."""
    root = Path(stiction.__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        if not {"cli", "plant"} & set(p.relative_to(root).parts[:1]):
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def simulated(kind: str, count: int, seed: int) -> Analysed:
    """The plants of ``kind`` at the gateway's 4 s, each loop analysed (the records of
    ``python -m bench plantwide`` before issue 29: same cache)."""
    src = inspect.getsource(plant_module) + inspect.getsource(plants_module)
    key = hashlib.sha256(f"{src}{kind}{count}{seed}{DURATION}{SAMPLE}".encode()).hexdigest()

    def make() -> Analysed:  # (the analysis is not in the key: the cache of issue 21)
        scenarios = plant_scenarios(kind, count, seed=seed)
        out = []
        for i in range(0, len(scenarios), 10):
            for rec in simulate_plants(scenarios[i:i + 10], duration=DURATION, sample=SAMPLE,
                                       seed=seed * 1000 + i):
                proc = processes(rec)
                out.append((rec, {n: analyze(rec.op[n], rec.pv[n], ts=rec.ts, process=proc[n])
                                  for n in rec.op}))
        return out

    return list(_pickled(CACHE / f"plants-{kind}-{key[:16]}.pickle", make))


def resampled(rec: PlantRecord, ts: float) -> PlantRecord:
    """``rec`` as a historian's interpolated export at ``ts`` seconds."""
    n = next(iter(rec.op.values())).size
    t = np.arange(n) * rec.ts
    grid = np.arange(0.0, t[-1] + 1e-9, ts)

    def at(series: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: np.interp(grid, t, v) for k, v in series.items()}

    return PlantRecord(rec.scenario, ts, at(rec.op), at(rec.pv), at(rec.indicators),
                       at(rec.vp))


def view(kind: str, count: int, seed: int, ts: float) -> Analysed:
    """The plants of ``kind`` at sample time ``ts`` (a view of :data:`VIEWS`), each loop
    analysed at that sampling."""
    base = simulated(kind, count, seed)
    if ts == SAMPLE:
        return base
    src = inspect.getsource(plant_module) + inspect.getsource(plants_module)
    key = hashlib.sha256(f"{src}{_code_key()}{kind}{count}{seed}{ts}".encode()).hexdigest()

    def make() -> Analysed:
        out = []
        for rec, _before in base:
            r = resampled(rec, ts)
            proc = processes(r)
            out.append((r, {n: analyze(r.op[n], r.pv[n], ts=ts, process=proc[n])
                            for n in r.op}))
        return out

    return list(_pickled(CACHE / f"plants-{kind}-{ts:g}s-{key[:16]}.pickle", make))


def tep_runs() -> list[tuple[Any, dict[str, Assessment]]]:
    """The corpus's TEP plant runs, every loop analysed (self-regulating: the analysis is
    told nothing); cached by stiction's code and the runs. Empty without the corpus;
    ``PLANTWIDE_CORPUS`` names another corpus folder (a copy being built: the runs so far)."""
    from lab import _cache  # noqa: PLC0415  (the built corpus)
    from lab.labels.corpus import load_plant_runs  # noqa: PLC0415

    folder = Path(os.environ.get("PLANTWIDE_CORPUS", str(_cache.corpus())))
    runs = [r for r in load_plant_runs(cache=folder) if r.source.startswith("tep-mode")]
    if not runs:
        return []
    key = hashlib.sha256((_code_key() + "".join(r.id for r in runs)).encode()).hexdigest()
    return list(_pickled(
        CACHE / f"plantwide-tep-{key[:16]}.pickle",
        lambda: [(r, {n: analyze(op, pv, ts=r.ts) for n, (op, pv) in r.loops.items()})
                 for r in runs]))
