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
from scipy import signal as sp_signal

import stiction
from stiction import Assessment, analyze
from stiction.scenarios import plant as plant_module
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import plant_scenarios

CACHE = Path(os.environ.get("PLANTWIDE_CACHE", Path(__file__).resolve().parents[1] / ".cache"))
DURATION, SAMPLE = 14400.0, 1
VIEWS = ("1", "4", "20", "60", "20h")
"""The views, by sample time in s: the simulation's own 1 s, the gateway's polling at 4 s and
a historian's exports at 20 and 60 s (every 4th, 20th or 60th sample, as the plant
simulator's exports are written: ``stiction simulate --plant --ts``); "h": as a historian
stores it too (:func:`historian`)."""
SENSOR_TAU, DEADBAND, QUANTUM = 30.0, 0.1, 0.02
"""The historian view's nuisance: each indicator read through a transmitter lag (s), every
signal stored only when it moved by ``DEADBAND`` since the value stored last (exception
compression: the export interpolates between stored values), written in steps of
``QUANTUM`` (OP in % of span, PV and indicators in their units about 50)."""

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


def _stored(x: np.ndarray) -> np.ndarray:
    """The samples of ``x`` an exception-compressing historian keeps (``DEADBAND``), and the
    last."""
    keep = [0]
    last = x[0]
    for i in range(1, x.size):
        if abs(x[i] - last) > DEADBAND:
            keep.append(i)
            last = x[i]
    if keep[-1] != x.size - 1:
        keep.append(x.size - 1)
    return np.asarray(keep)


def historian(rec: PlantRecord, ts: float) -> PlantRecord:
    """``rec`` as a historian stores and exports it (:data:`SENSOR_TAU`): indicators through a
    transmitter lag, every signal compressed and quantised, the export every ``ts`` s."""
    n = next(iter(rec.op.values())).size
    t = np.arange(n) * rec.ts
    grid = np.arange(0.0, t[-1] + 1e-9, ts)
    a = float(np.exp(-rec.ts / SENSOR_TAU))

    def lagged(x: np.ndarray) -> np.ndarray:
        return np.asarray(sp_signal.lfilter([1.0 - a], [1.0, -a], x - x[0]) + x[0])

    def export(series: dict[str, np.ndarray], lag: bool = False) -> dict[str, np.ndarray]:
        out = {}
        for k, v in series.items():
            x = lagged(v) if lag else v
            kept = _stored(x)
            out[k] = np.round(np.interp(grid, t[kept], x[kept]) / QUANTUM) * QUANTUM
        return out

    return PlantRecord(rec.scenario, ts, export(rec.op), export(rec.pv),
                       export(rec.indicators, lag=True),
                       {k: np.interp(grid, t, v) for k, v in rec.vp.items()})


def view_ts(name: str) -> tuple[float, bool]:
    """A view's sample time and whether it is a historian's (:data:`VIEWS`)."""
    return float(name.rstrip("h")), name.endswith("h")


def view(kind: str, count: int, seed: int, name: str) -> Analysed:
    """The plants of ``kind`` in view ``name`` (:data:`VIEWS`), each loop analysed at that
    sampling."""
    base = simulated(kind, count, seed)
    ts, stored = view_ts(name)
    if ts == SAMPLE and not stored:
        return base
    key = _plants_key(kind, count, seed) + _code_key() + (
        f"{SENSOR_TAU:g}-{DEADBAND:g}-{QUANTUM:g}" if stored else "")

    def make() -> Analysed:
        out = []
        for rec, _before in base:
            r = historian(rec, ts) if stored else resampled(rec, ts)
            proc = processes(r)
            out.append((r, {n: analyze(r.op[n], r.pv[n], ts=ts, process=proc[n])
                            for n in r.op}))
        return out

    return list(_pickled(CACHE / f"plants-{kind}-{name}s-{key}.pickle", make))


def tep_runs(shared: bool = False) -> list[tuple[Any, dict[str, Assessment]]]:
    """The corpus's TEP plant runs (the 457 revised Tennessee Eastman runs of 9 loops, the
    other measurements as indicators: ``tep-mode*``), or with ``shared`` the 29 shared ones
    of ../shared/data/tep-sticky-valves (2 loops, no indicators: ``tep-shared``), every loop
    analysed (self-regulating: the analysis is told nothing); cached by stiction's code and
    the runs. Empty without the corpus; ``PLANTWIDE_CORPUS`` names another corpus folder (a
    copy being built: the runs so far)."""
    from lab import _cache  # noqa: PLC0415  (the built corpus)
    from lab.labels.corpus import load_plant_runs  # noqa: PLC0415

    if shared:
        runs = load_plant_runs(sources=["tep-shared"])
    else:
        folder = Path(os.environ.get("PLANTWIDE_CORPUS", str(_cache.corpus())))
        runs = [r for r in load_plant_runs(cache=folder) if r.source.startswith("tep-mode")]
    if not runs:
        return []
    key = hashlib.sha256((_code_key() + "".join(r.id for r in runs)).encode()).hexdigest()
    return list(_pickled(
        CACHE / f"plantwide-tep-{key[:16]}.pickle",
        lambda: [(r, {n: analyze(op, pv, ts=r.ts) for n, (op, pv) in r.loops.items()})
                 for r in runs]))
