"""The plant-wide benchmark's data: the project's plants at the gateway's sampling and
resampled as a historian exports them, each loop analysed; the TEP plant runs. Cached in
bench/.cache by the generators' and the analysis' source."""

from __future__ import annotations

import dataclasses
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
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import plant_scenarios

CACHE = Path(os.environ.get("PLANTWIDE_CACHE", Path(__file__).resolve().parent / ".cache"))
DURATION, SAMPLE = 14400.0, 1
VIEWS = (1.0, 4.0, 20.0, 60.0)
"""Sample times of the views, s: the simulation's own 1 s, the gateway's polling at 4 s and
a historian's exports at 20 and 60 s (every 4th, 20th or 60th sample, as the plant
simulator's exports are written: ``stiction simulate --plant --ts``)."""

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
    """The per-loop analysis' code: stiction/ without the plant view, the CLI and the
    scenarios (a change to the plant view analyses nothing again; the plants simulated are
    keyed by what was drawn, :func:`_plants_key`)."""
    root = Path(stiction.__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        if not {"cli", "plant", "scenarios"} & set(p.relative_to(root).parts[:1]):
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def _drawn(x: Any) -> str:
    """``x`` (the scenarios drawn) as text, a dataclass's fields at their defaults left out
    (a field added with a default that changes nothing keeps the key)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        parts = [f"{f.name}={_drawn(getattr(x, f.name))}" for f in dataclasses.fields(x)
                 if f.default is dataclasses.MISSING or getattr(x, f.name) != f.default]
        return f"{type(x).__name__}({', '.join(parts)})"
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_drawn(v) for v in x) + "]"
    if isinstance(x, dict):
        return "{" + ", ".join(f"{k!r}: {_drawn(v)}" for k, v in x.items()) + "}"
    return repr(x)


def _plants_key(kind: str, count: int, seed: int) -> str:
    """The plants drawn (their parameters) and the simulator's code: the same plants give
    the same key in any tree (the baseline's too)."""
    drawn = _drawn(plant_scenarios(kind, count, seed=seed))
    src = inspect.getsource(plant_module)
    return hashlib.sha256(f"{src}{drawn}{DURATION}{SAMPLE}{seed}".encode()).hexdigest()[:16]


def simulated(kind: str, count: int, seed: int) -> Analysed:
    """The plants of ``kind`` at the simulation's 1 s, each loop analysed."""
    key = _plants_key(kind, count, seed) + _code_key()

    def make() -> Analysed:
        scenarios = plant_scenarios(kind, count, seed=seed)
        out = []
        for i in range(0, len(scenarios), 10):
            for rec in simulate_plants(scenarios[i:i + 10], duration=DURATION, sample=SAMPLE,
                                       seed=seed * 1000 + i):
                proc = processes(rec)
                out.append((rec, {n: analyze(rec.op[n], rec.pv[n], ts=rec.ts, process=proc[n])
                                  for n in rec.op}))
        return out

    return list(_pickled(CACHE / f"plants-{kind}-{key}.pickle", make))


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
    key = _plants_key(kind, count, seed) + _code_key()

    def make() -> Analysed:
        out = []
        for rec, _before in base:
            r = resampled(rec, ts)
            proc = processes(r)
            out.append((r, {n: analyze(r.op[n], r.pv[n], ts=ts, process=proc[n])
                            for n in r.op}))
        return out

    return list(_pickled(CACHE / f"plants-{kind}-{ts:g}s-{key}.pickle", make))


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
