"""Every result of the analysis, bit for bit: a guard for changes that must not move one.

Analyses the windows the accuracy benchmarks use and records every field of every
``Assessment`` (verdict, reason, confidence, sizes, every test's value, vote and note; floats
by ``repr``, which round-trips exactly), then prints one digest per source:

- ``plant``: the 80 plant records, ``tep``: the 58 shared Tennessee Eastman runs, ``cases``:
  the windows of ``../shared/data/cases`` (as ``analyze(op, pv, ts=ts)``, as a new user would);
- ``sims``: the realistic simulations of ``bench real_data`` (process unknown and given);
- ``paper``: every row of the paper's Tables 4-9 (``reproduce``: verdict and the sizes even
  where detection does not say stiction);
- ``false_alarms``: the first seed of ``bench false_alarms``' sweep.

``python -m bench fingerprint`` prints the digests;
``python -m bench.accuracy.fingerprint --save FILE`` also writes every result (JSON),
``--against FILE`` compares with a saved run and lists every window that moved. A
refactoring that claims "same results" shows the same digests before and after.
"""

from __future__ import annotations

import csv
import hashlib
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from lab.sources import records
from lab.sources.realistic import sim_cases
from stiction import Assessment, analyze
from stiction.paper import reproduce
from stiction.scenarios import scenario, simulate

CASES = records.SHARED / "cases"


def _record(a: Assessment) -> dict[str, Any]:
    return json.loads(json.dumps(a.to_dict(), default=repr))


def _shared() -> Iterator[tuple[str, str, dict[str, Any]]]:
    for c in records.plant_cases():
        yield "plant", c.name, _record(analyze(c.op, c.pv, ts=c.ts))
    for c in records.tep_cases():
        yield "tep", c.name, _record(analyze(c.op, c.pv, ts=c.ts))
    for path in sorted(CASES.glob("*.csv")):
        with path.open() as fh:
            rows = list(csv.DictReader(fh))
        op = np.array([float(r["op"]) for r in rows])
        pv = np.array([float(r["pv"]) for r in rows])
        t = np.array([float(r["t"]) for r in rows])
        yield "cases", path.name, _record(analyze(op, pv, ts=float(np.median(np.diff(t)))))


def _sims() -> Iterator[tuple[str, str, dict[str, Any]]]:
    for c in sim_cases(14):
        yield "sims", f"{c.name}/unknown", _record(analyze(c.op, c.pv, ts=c.ts))
        yield "sims", f"{c.name}/given", _record(analyze(c.op, c.pv, ts=c.ts,
                                                         process=c.process))


def _paper() -> Iterator[tuple[str, str, dict[str, Any]]]:
    for noise in (0.0, 0.05):
        for r in reproduce.reproduce(noise=noise):
            rec = _record(r.assessment)
            rec["sizes"] = [repr(r.fd), repr(r.fs), r.multi_jump]
            yield "paper", f"{noise}/{r.paper.table}/{r.paper.case}", rec


def _false_alarms() -> Iterator[tuple[str, str, dict[str, Any]]]:
    for name in ("healthy", "disturbance", "aggressive-tuning"):
        for load_sd, tau in ((0.005, 30.0), (0.02, 600.0)):
            res = simulate(scenario(name, load_sd=load_sd, load_tau=tau), duration=7200.0,
                           noise=0.2, seed=0)
            for ts in (1, 10):
                op, pv, w = res.op[::ts], res.pv[::ts], 3600 // ts
                for start in range(0, op.size - w + 1, w // 2):
                    a = analyze(op[start:start + w], pv[start:start + w], ts=float(ts))
                    yield "false_alarms", f"{name}/{load_sd}/{tau}/{ts}/{start}", _record(a)


def fingerprint() -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for gen in (_shared, _paper, _false_alarms, _sims):
        for source, name, rec in gen():
            out.setdefault(source, {})[name] = rec
    return out


def digests(results: dict[str, dict[str, Any]]) -> dict[str, str]:
    return {source: hashlib.sha256(json.dumps(recs, sort_keys=True).encode()).hexdigest()[:16]
            for source, recs in results.items()}


def compare(results: dict[str, dict[str, Any]], saved: dict[str, dict[str, Any]]) -> int:
    moved = 0
    for source in sorted(set(results) | set(saved)):
        now, then = results.get(source, {}), saved.get(source, {})
        for name in sorted(set(now) | set(then)):
            if now.get(name) != then.get(name):
                moved += 1
                if moved <= 20:
                    print(f"  moved: {source} {name}: {then.get(name)} -> {now.get(name)}")
    return moved


def main(argv: list[str] | None = None) -> None:
    args = argv or []
    if not records.PLANT.exists():
        print(f"fingerprint: skipped, {records.SHARED} not found")
        return
    t0 = time.perf_counter()
    results = fingerprint()
    print(f"== fingerprint of every result ({time.perf_counter() - t0:.0f} s) ==")
    for source, digest in digests(results).items():
        print(f"  {source:13s} {len(results[source]):5d} windows  {digest}")
    if "--save" in args:
        Path(args[args.index("--save") + 1]).write_text(json.dumps(results, sort_keys=True))
    if "--against" in args:
        saved = json.loads(Path(args[args.index("--against") + 1]).read_text())
        moved = compare(results, saved)
        total = sum(len(r) for r in results.values())
        print(f"  against the saved run: {moved} of {total} windows moved")


if __name__ == "__main__":
    main(sys.argv[1:])
