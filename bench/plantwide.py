"""Plant-wide: which loops share an oscillation and which is its source, per scenario.

Data (each analysed as the gateway would: every loop's window with ``stiction.analyze``,
the process type given, then ``stiction.plant.analyze_plant`` over all of them):

- **own plants** (:mod:`stiction.scenarios.plants`): ``sticky`` (a sticky valve feeding 2-6
  loops), ``cascade`` (the sticky valve in the inner loop of a declared cascade), ``two``
  (two sticky valves), ``external`` (a periodic load from outside, good valves), ``tuning``
  (an aggressively tuned loop feeding others), ``quiet`` (loads only); 4 h at 4 s, two
  seeds. A plant counts for "source first" when its sticky valve's cycle is visible and
  reaches another loop (:func:`reaches`).
- **TEP plant runs** (``bench/corpus.py``'s ``load_plant_runs``, when the corpus is built):
  the XMV loops and XMEAS indicators of each revised Tennessee Eastman run.

Per kind, in one run: groups found, the true source ranked first among its group's loops
(either, when a group holds two true sources), named as the source, external cycles
reported as having no loop source, loops other than the source called ``stiction`` before
and after the plant view (``propagated`` after), and true sources lost (a sticky valve
called ``stiction`` before, not after).

``python -m bench plantwide``; ``PLANTWIDE_PLANTS=N`` plants per kind and seed (default 30).
"""

from __future__ import annotations

import collections
import hashlib
import inspect
import os
import pickle
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal as sp_signal

from stiction import Assessment, Verdict, analyze
from stiction.plant import PlantAssessment, analyze_plant
from stiction.plant.groups import BAND
from stiction.plant.spectra import MIN_CYCLES, spectra
from stiction.scenarios import plant as plant_module
from stiction.scenarios import plants as plants_module
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import PLANT_KINDS, plant_scenarios
from stiction.signal.oscillation import detect_oscillation

CACHE = Path(__file__).resolve().parent / ".cache"
SEEDS = (1, 2)  # the thresholds of stiction.plant were set on these
HELD_OUT = (3, 4)  # ... and are measured on these too
REACH = 0.8  # coherence with the sticky valve's position at its cycle's frequency
VISIBLE = 0.05  # ... and the share of the signal's power in the cycle's band
DURATION, SAMPLE = 14400.0, 4


def _cascades(rec: PlantRecord) -> dict[str, str]:
    return {ln.source: ln.target for ln in rec.scenario.links if ln.kind == "setpoint"}


def _processes(rec: PlantRecord) -> dict[str, str]:
    return {lp.name: "integrating" if lp.integrating else "self-regulating"
            for lp in rec.scenario.loops}


def records(kind: str, count: int, seed: int) -> list[tuple[PlantRecord, dict[str, Assessment]]]:
    """The plants of ``kind`` simulated, each loop analysed; cached by the generator's
    source."""
    src = inspect.getsource(plant_module) + inspect.getsource(plants_module)
    key = hashlib.sha256(f"{src}{kind}{count}{seed}{DURATION}{SAMPLE}".encode()).hexdigest()
    path = CACHE / f"plants-{kind}-{key[:16]}.pickle"
    if path.exists():
        with path.open("rb") as fh:
            cached: list[tuple[PlantRecord, dict[str, Assessment]]] = pickle.load(fh)
        return cached
    scenarios = plant_scenarios(kind, count, seed=seed)
    out = []
    for i in range(0, len(scenarios), 10):
        for rec in simulate_plants(scenarios[i:i + 10], duration=DURATION, sample=SAMPLE,
                                   seed=seed * 1000 + i):
            proc = _processes(rec)
            out.append((rec, {n: analyze(rec.op[n], rec.pv[n], ts=rec.ts, process=proc[n])
                              for n in rec.op}))
    CACHE.mkdir(exist_ok=True)
    with path.open("wb") as fh:
        pickle.dump(out, fh)
    return out


def reaches(rec: PlantRecord, loop: str) -> bool:
    """Does the sticky valve of ``loop`` cycle regularly, at least ``MIN_CYCLES`` times in
    the window, visibly (its loop's OP or PV oscillates regularly at that period) and does
    its cycle visibly reach another loop (OP or PV coherent with the valve's position at the
    cycle's frequency, at least ``REACH``, with at least ``VISIBLE`` of its power in the
    cycle's band)? The truth, from the valve position no analysis sees."""
    vp = rec.vp[loop]
    o = detect_oscillation(vp - vp.mean())
    if not (o.oscillating and o.regularity > 1.0 and o.period is not None
            and vp.size / o.period >= MIN_CYCLES):
        return False
    own = [detect_oscillation(x - x.mean()) for x in (rec.op[loop], rec.pv[loop])]
    if not any(w.oscillating and w.period is not None and abs(w.period / o.period - 1.0) <= BAND
               for w in own):
        return False
    seg = min(2048, vp.size // 2)
    others = [x for name in rec.op if name != loop for x in (rec.op[name], rec.pv[name])]
    if not others:
        return False
    f0 = 1.0 / o.period
    share = spectra(np.array(others)).band(f0 * (1.0 - BAND), f0 * (1.0 + BAND))
    for x, sh in zip(others, share, strict=True):
        f, coh = sp_signal.coherence(vp, x, nperseg=seg)
        if np.nan_to_num(coh[int(np.argmin(np.abs(f - f0)))]) >= REACH and sh >= VISIBLE:
            return True
    return False


def score(kind: str, rec: PlantRecord, before: dict[str, Assessment],
          view: PlantAssessment) -> collections.Counter[str]:
    """What one plant counts for (module doc)."""
    c: collections.Counter[str] = collections.Counter()
    after = view.apply(before)
    sources = set(rec.scenario.sources)
    c["plants"] += 1
    c["groups"] += len(view.groups)
    for name, a in before.items():
        own = name in sources and kind not in ("external", "tuning")
        called = [x.verdict == Verdict.STICTION for x in (a, after[name])]
        if own:
            c["sources called before"] += called[0]
            c["sources lost"] += called[0] and not called[1]
        else:
            c["others called before"] += called[0]
            c["others called after"] += called[1]
    if kind in ("sticky", "cascade", "two"):
        for src in sources:
            if not reaches(rec, src):
                continue
            c["sources reaching others"] += 1
            g = next((g for g in view.groups if src in g.loops), None)
            if g is None:
                continue
            c["in a group"] += 1
            # a group holding two true sources: either first is the right answer
            c["ranked first"] += g.ranking[0].loop in sources
            c["named"] += g.source == src or src in g.also_sources
            c["first by harmonics"] += max(g.ranking, key=lambda e: e.harmonics).loop == src
            c["first by valve gain"] += max(
                g.ranking, key=lambda e: -9.0 if e.valve_gain is None else e.valve_gain
            ).loop == src
        c["wrong loop named"] += sum(1 for g in view.groups if g.source not in (None, *sources))
    elif kind == "external":
        c["external groups"] += len(view.groups)
        c["reported without a loop source"] += sum(1 for g in view.groups if g.source is None)
    else:
        c["a loop named"] += sum(1 for g in view.groups if g.source is not None)
    if kind == "two" and all(reaches(rec, src) for src in sources):
        c["two visible sources"] += 1
        tops = {g.number for g in view.groups if g.ranking[0].loop in sources}
        c["both found as two groups"] += len(tops) == 2 and \
            {g.ranking[0].loop for g in view.groups if g.number in tops} == sources
    return c


def run(count: int, seeds: tuple[int, ...] = SEEDS) -> dict[str, collections.Counter[str]]:
    totals: dict[str, collections.Counter[str]] = {}
    for kind in PLANT_KINDS:
        c: collections.Counter[str] = collections.Counter()
        for seed in seeds:
            for rec, before in records(kind, count, seed):
                view = analyze_plant({n: (rec.op[n], rec.pv[n]) for n in rec.op}, ts=rec.ts,
                                     indicators=rec.indicators, assessments=before,
                                     processes=_processes(rec), cascades=_cascades(rec))
                c += score(kind, rec, before, view)
        totals[kind] = c
    return totals


def _pct(a: int, b: int) -> str:
    return f"{a}/{b} ({100.0 * a / b:.0f} %)" if b else "-"


def report(totals: dict[str, Any]) -> None:
    print(f"{'kind':9s} {'plants':>6s} {'groups':>6s} {'reach':>5s} {'grouped':>7s}  "
          "source first   named          by harmonics   by valve gain  others called "
          "stiction before -> after   sources lost")
    for kind, c in totals.items():
        line = (f"{kind:9s} {c['plants']:6d} {c['groups']:6d} "
                f"{c['sources reaching others']:5d} {c['in a group']:7d}  "
                f"{_pct(c['ranked first'], c['sources reaching others']):14s} "
                f"{_pct(c['named'], c['sources reaching others']):14s} "
                f"{_pct(c['first by harmonics'], c['sources reaching others']):14s} "
                f"{_pct(c['first by valve gain'], c['sources reaching others']):14s} "
                f"{c['others called before']:6d} -> {c['others called after']:<6d}"
                f"{'':22s}{c['sources lost']}/{c['sources called before']}")
        print(line)
    ext = totals.get("external", collections.Counter())
    two = totals.get("two", collections.Counter())
    print(f"external cycles reported without a loop source: "
          f"{_pct(ext['reported without a loop source'], ext['external groups'])}; "
          f"two sources found as two groups, each first in its own: "
          f"{_pct(two['both found as two groups'], two['two visible sources'])}"
          f"; a loop named in tuning/quiet plants: "
          f"{totals.get('tuning', {}).get('a loop named', 0)}/"
          f"{totals.get('quiet', {}).get('a loop named', 0)}")


def tep_runs() -> list[tuple[Any, dict[str, Assessment]]]:
    """The corpus's TEP plant runs, every loop analysed (self-regulating: the analysis is
    told nothing); cached by stiction's code and the runs. Empty without the corpus."""
    from lab.features.rows import code_key as _code_key  # noqa: PLC0415
    from lab.labels.corpus import load_plant_runs  # noqa: PLC0415  (the built corpus)

    runs = [r for r in load_plant_runs() if r.source.startswith("tep-mode")]
    if not runs:
        return []
    key = hashlib.sha256((_code_key() + "".join(r.id for r in runs)).encode()).hexdigest()
    path = CACHE / f"plantwide-tep-{key[:16]}.pickle"
    if path.exists():
        with path.open("rb") as fh:
            cached: list[tuple[Any, dict[str, Assessment]]] = pickle.load(fh)
        return cached
    out = [(r, {n: analyze(op, pv, ts=r.ts) for n, (op, pv) in r.loops.items()})
           for r in runs]
    with path.open("wb") as fh:
        pickle.dump(out, fh)
    return out


def tep() -> None:
    """Issue 21's TEP lines: a sticking valve whose cycle reaches other loops (its loop is
    in a group) ranked first, no other loop called ``stiction``; without one, no loop named
    the source of a cycle with a ``stiction`` verdict of its own."""
    c: collections.Counter[str] = collections.Counter()
    for run_, before in tep_runs():
        view = analyze_plant(dict(run_.loops), ts=run_.ts, indicators=run_.indicators,
                             assessments=before)
        after = view.apply(before)
        sticky = set(run_.sticky_loops)
        for name in before:
            if name not in sticky:
                c["others called before"] += before[name].verdict == Verdict.STICTION
                c["others called after"] += after[name].verdict == Verdict.STICTION
        if sticky:
            c["sticky runs"] += 1
            for src in sticky:
                g = next((g for g in view.groups if src in g.loops), None)
                if g is None:
                    continue
                c["reaching others"] += 1
                c["ranked first"] += g.ranking[0].loop in sticky  # two (IDV 19): either
                c["named"] += g.source == src or src in g.also_sources
                c["sticky lost"] += before[src].verdict == Verdict.STICTION and \
                    after[src].verdict != Verdict.STICTION
        else:
            c["clean runs"] += 1
            c["valve source named"] += sum(
                1 for g in view.groups for n in (g.source, *g.also_sources)
                if n is not None and after[n].verdict == Verdict.STICTION)
    if not c:
        print("== plant-wide: TEP runs: skipped (python -m bench corpus builds them) ==")
        return
    print(f"== plant-wide: TEP runs ({c['sticky runs']} with a sticking valve, "
          f"{c['clean runs']} without) ==")
    print(f"  sticking valve's cycle in a group: {c['reaching others']}; ranked first "
          f"{_pct(c['ranked first'], c['reaching others'])}, named "
          f"{_pct(c['named'], c['reaching others'])}, its stiction call lost "
          f"{c['sticky lost']}")
    print(f"  other loops called stiction, before -> after the plant view: "
          f"{c['others called before']} -> {c['others called after']}")
    print(f"  runs without a sticking valve: a loop named source with a stiction verdict "
          f"{c['valve source named']} times")


def main() -> None:
    t0 = time.perf_counter()
    count = int(os.environ.get("PLANTWIDE_PLANTS", "30"))
    warnings.filterwarnings("ignore", category=RuntimeWarning)  # coherence of a flat series
    for label, seeds in (("development", SEEDS), ("held out", HELD_OUT)):
        print(f"== plant-wide: own plants, {label} seeds {seeds} ({count} per kind and "
              "seed) ==")
        report(run(count, seeds))
    tep()
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
