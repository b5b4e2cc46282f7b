"""The development corpus (issues 24 and 21): labelled loop windows and multi-loop plant runs
to learn the stiction decision from and to measure it and the plant-wide analysis on.

``python -m lab corpus`` (``make corpus``) builds what ``lab/.cache/corpus`` lacks (one
process; a Tennessee Eastman run and each realistic set are cached as soon as made, so an
interrupted build resumes; lab/_cache.py says where an older checkout's corpus is found)
and prints windows per source and cause class. Everything is seeded: the same code and
tep-studio build the same corpus. ``load_windows()`` and ``load_plant_runs()`` read the
cache (no tep-studio needed); docs/corpus.md describes it.

Sources (the fold keys of :data:`lab._types.SOURCES`):

- ``tep-mode1`` .. ``tep-mode6``: tep-studio's revised Tennessee Eastman model under
  Ricker's decentralised control (lab/sources/tep.py), the runs of lab/sources/tep_plan.py:
  normal operation, each disturbance alone at 2 of 3 magnitudes, pairs, the sticky valves
  (IDV 14, 15, 19) at 0.5-12 % bands. A run continues its mode's settled state (36 h of
  normal operation); disturbances start 0.5 h in; the first 4 h after the onset are
  skipped, the next 24 h kept. Each loop whose output is a valve (9 of them) gives:

  * ``gateway`` windows: 2 h at 1.8 s (Ricker's controller period; 4,000 samples), as the
    gateway keeps a loop at about 1 s: two per loop and run, at 6.5 and 18.5 h;
  * a ``historian`` window: the 24 h as snapshots every 36 s (2,400 samples), the sample
    time of the revised model's studies and of plant historians (10 s - 1 min);
  * a ``study`` window: the 24 h as 180 s means (480 samples), the sample time of the
    classic TEP data sets (Braatz), for slow loops whose cycles last an hour.

- ``realistic``: ``stiction.scenarios.realistic`` with every cause in ``CAUSES``, seeds 11-15,
  30 records each (its own sample times, 1-60 s, and lengths).
- ``plant``: the 80 plant records (../shared/data/plant-stictiongpt), a run per tag.
- ``tep-shared``: the 58 third-party TEP records (../shared/data/tep-sticky-valves), a run
  per simulation (its two loops).
- ``cases``: the single cases of ../shared/data/cases whose right answer is stated.

Labels: lab/labels/rules.py (a sticky valve's loop by what its valve did in the window;
every other loop against its mode's normal runs); the windows are cut in
lab/windows/tep.py.
"""

from __future__ import annotations

import collections
import time
from collections.abc import Iterable
from pathlib import Path

from .. import _cache
from .._types import CAUSE_CLASSES, SOURCES, PlantRun, Window, counts, folds
from ..sources import realistic, records, tep_plan
from ..windows import tep
from .tep import tep_records

__all__ = ["SOURCES", "PlantRun", "Window", "folds", "load_plant_runs", "load_windows",
           "main"]


def _tep(cache: Path) -> tuple[list[Window], list[PlantRun]]:
    return tep_records(tep.load(tep_plan.plan(), cache / "tep"))


def load_windows(sources: Iterable[str] | None = None, views: Iterable[str] | None = None,
                 cache: Path | None = None) -> list[Window]:
    """Every window of the corpus (of ``sources`` and ``views`` if given) in ``cache`` (the
    built corpus's folder if None); the TEP and realistic parts as far as built (run
    ``python -m lab corpus`` first)."""
    cache = _cache.corpus() if cache is None else cache
    want = set(SOURCES if sources is None else sources)
    unknown = want - set(SOURCES)
    if unknown:
        raise ValueError(f"unknown sources {sorted(unknown)}; known: {', '.join(SOURCES)}")
    out: list[Window] = []
    if any(s.startswith("tep-mode") for s in want):
        out += [w for w in _tep(cache)[0] if w.source in want]
    if "realistic" in want:
        out += realistic.realistic_windows(cache / "realistic")
    if "plant" in want:
        out += records.plant_windows()
    if "tep-shared" in want:
        out += records.shared_tep_windows()
    if "cases" in want:
        out += records.case_windows()
    if views is not None:
        keep = set(views)
        out = [w for w in out if w.view in keep]
    return out


def load_plant_runs(sources: Iterable[str] | None = None, cache: Path | None = None
                    ) -> list[PlantRun]:
    """Every multi-loop run: the TEP runs (9 loops at 36 s, the other XMEAS as indicators)
    and the shared TEP runs (2 loops, no indicators)."""
    cache = _cache.corpus() if cache is None else cache
    want = set(SOURCES if sources is None else sources)
    out = [r for r in _tep(cache)[1] if r.source in want] \
        if any(s.startswith("tep-mode") for s in want) else []
    if "tep-shared" in want:
        out += records.shared_tep_plant_runs(records.shared_tep_windows())
    return out


def build(cache: Path | None = None) -> None:
    cache = _cache.corpus() if cache is None else cache
    t0, c0 = time.perf_counter(), time.process_time()
    print(f"corpus: building what {cache} lacks")
    done = tep.build(tep_plan.plan(), cache / "tep", print)
    print(f"  Tennessee Eastman: {done} runs simulated")
    done = realistic.build_realistic(cache / "realistic", print)
    print(f"  realistic: {done} sets drawn")
    print(f"  built in {time.perf_counter() - t0:.0f} s ({time.process_time() - c0:.0f} s CPU)")


def summary(windows: list[Window], plant_runs: list[PlantRun]) -> None:
    table = counts(windows)
    classes = [c for c in CAUSE_CLASSES if any(k[1] == c for k in table)]
    print(f"\n{'source':<12}" + "".join(f"{c[:11]:>12}" for c in classes)
          + f"{'total':>8}{'sticky':>8}")
    for source in [s for s in SOURCES if any(k[0] == s for k in table)]:
        row = [table.get((source, c), 0) for c in classes]
        sticky = sum(w.sticky for w in windows if w.source == source)
        print(f"{source:<12}" + "".join(f"{n:>12}" for n in row)
              + f"{sum(row):>8}{sticky / max(sum(row), 1):>8.0%}")
    total = [sum(table.get((s, c), 0) for s in SOURCES) for c in classes]
    print(f"{'all':<12}" + "".join(f"{n:>12}" for n in total) + f"{sum(total):>8}"
          f"{sum(w.sticky for w in windows) / max(len(windows), 1):>8.0%}")
    views = collections.Counter((w.view, w.ts) for w in windows)
    print("views: " + ", ".join(f"{v} {ts:g} s: {n}" for (v, ts), n in sorted(views.items())))
    fold = folds(windows)
    print(f"folds: {len(fold)}, runs: {len({w.run for w in windows})}; plant runs: "
          f"{len(plant_runs)} ({sum(bool(r.sticky_loops) for r in plant_runs)} with a "
          f"sticky valve, {sum(bool(r.external) for r in plant_runs)} with a disturbance)")


def main() -> None:
    t0 = time.perf_counter()
    build()
    windows = load_windows()
    plant_runs = load_plant_runs()
    summary(windows, plant_runs)
    print(f"(corpus: {time.perf_counter() - t0:.0f} s)")
