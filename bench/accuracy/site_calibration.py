"""Does the crew's feedback teach a site its calibration? (issue 39) Two tables, in one run.

**Simulated sites** whose valves differ from the development corpus (bench/accuracy/_sites.py:
sticky valves gripping harder one way with less overshoot, a historian sampling 8 times
slower, both; valves with lost motion and no slip, which the crew finds as a dead band):
72 loops each, 24 with a sticky valve. Every loop is analysed as the gateway analyses it
(its process and OP range known). Each site is split in two halves at random; the crew
checks the 20 valves at the top of one half's shipped list (worst first: what a crew does
with it) and records what it finds; the site's calibration is fitted on those 20 findings
(stiction.ranking.fit_site, the rule of docs/configuration.md) and judges the other half
(recalibrate), and the other way round, so that every loop is judged once by a fit that never
saw it. The table: the `stiction` calls before (shipped) and after (the site's), how many of
them are sticky (precision) and how many of the sticky valves are called (recall).

**Plant records** (../shared/data/plant-stictiongpt, 80 records of 34 tags; read its
README's caveats): leave one tag out. For each tag, the other tags' records are findings
(the label says what a crew would have found), the calibration fitted on them judges the
tag's records; the calls beside the shipped ones, per record and per tag (the majority of
its records), with the calibration's verdict (fitted, or why the shipped one stayed) per
fold. ``valve_not_responding`` is not recalibrated (it has no confidence) and counts as a
call, as in ``bench real_data``.
"""

from __future__ import annotations

import collections
import csv
import dataclasses
import time
from collections.abc import Sequence

import numpy as np

from bench.accuracy._sites import SITES, site_records
from lab.sources.records import PLANT
from stiction import Assessment, Verdict, analyze
from stiction.ranking import SiteCalibration, fit_site, recalibrate, shipped

FINDINGS = 20
CALLS = (Verdict.STICTION, Verdict.VALVE_NOT_RESPONDING)


@dataclasses.dataclass(frozen=True)
class Judged:
    name: str
    sticky: bool
    shipped: Assessment
    site: Assessment | None = None


def _counts(rows: Sequence[Judged], which: str) -> tuple[int, int, int]:
    """(calls, sticky among them, sticky in all) of ``rows``' shipped or site verdicts."""
    calls = hits = 0
    for r in rows:
        a = r.shipped if which == "shipped" else (r.site or r.shipped)
        if a.verdict in CALLS:
            calls += 1
            hits += r.sticky
    return calls, hits, sum(r.sticky for r in rows)


def _said(calls: int, hits: int, sticky: int) -> str:
    precision = f"{100 * hits / calls:3.0f} %" if calls else "  - "
    recall = f"{100 * hits / sticky:3.0f} %" if sticky else "  - "
    return f"{calls:>3} calls, {hits:>2} sticky: precision {precision}, recall {recall}"


def _fit(c: Sequence[float], y: Sequence[bool], keys: Sequence[str]) -> SiteCalibration:
    return fit_site(np.array(c, dtype=np.float64), np.array(y, dtype=bool), keys=list(keys),
                    stiction_at=shipped()[0])


def _judge(rows: list[Judged], cal: SiteCalibration) -> list[Judged]:
    at, no = shipped()
    return [dataclasses.replace(r, site=recalibrate(r.shipped, cal, stiction_at=at,
                                                    no_stiction_at=no)) for r in rows]


def _fold(rows: list[Judged], train: list[int], test: list[int]
          ) -> tuple[list[Judged], SiteCalibration, str]:
    """The crew checks the top of ``train``'s shipped list; the fit judges ``test``."""
    order = sorted(train, key=lambda k: -(rows[k].shipped.confidence or 0.0))
    checked = order[:FINDINGS]
    cal = _fit([rows[k].shipped.confidence or 0.0 for k in checked],
               [rows[k].sticky for k in checked], [rows[k].name for k in checked])
    sticky = sum(rows[k].sticky for k in checked)
    return _judge([rows[k] for k in test], cal), cal, f"{sticky} st, {len(checked) - sticky} ok"


def simulated_sites() -> None:
    print(f"\nSimulated sites, two folds each: the crew checks the top {FINDINGS} of one half's "
          "shipped list; the site's calibration fitted on those findings judges the other half")
    print(f"{'site':<11} {'loops':>5}  {'findings':<24} {'calibration':<14} "
          f"{'before (shipped)':<44} after (the site's)")
    for site in SITES:
        t0 = time.perf_counter()
        recs = site_records(site)
        rows = [Judged(f"{site}-{k}", bool(r["sticky"]),
                       analyze(r["op"], r["pv"], ts=r["ts"], process=r["process"],
                               op_range=r["op_range"])) for k, r in enumerate(recs)]
        perm = np.random.default_rng(39).permutation(len(rows)).tolist()
        half = [perm[::2], perm[1::2]]
        judged, said, cals = [], [], []
        for train, test in ((half[0], half[1]), (half[1], half[0])):
            got, cal, found = _fold(rows, train, test)
            judged += got
            said.append(found)
            cals.append(cal)
        names = "/".join(c.name for c in cals)
        print(f"{site:<11} {len(rows):>5}  {' | '.join(said):<24} {names:<14} "
              f"{_said(*_counts(judged, 'shipped')):<44} {_said(*_counts(judged, 'site'))}")
        for k, cal in enumerate(cals):
            print(f"{'':<11} fold {k + 1}: {cal.why}; scale {cal.scale:.2f}, offset "
                  f"{cal.offset:.2f}")
        print(f"{'':<11} ({time.perf_counter() - t0:.0f} s)")


def _plant() -> list[tuple[str, bool, Assessment]]:
    with (PLANT / "labels.csv").open(newline="") as fh:
        labels = list(csv.DictReader(fh))
    out = []
    for lab in labels:
        data = np.genfromtxt(PLANT / f"{lab['loop']}.csv", delimiter=",", names=True)
        out.append((lab["tag"], lab["label"] == "stiction",
                    analyze(data["op"], data["pv"], ts=float(lab["ts_s"]))))
    return out


def plant_records() -> None:
    if not (PLANT / "labels.csv").exists():
        print(f"\nPlant records: not found ({PLANT}); skipped")
        return
    recs = _plant()
    tags = sorted({t for t, _s, _a in recs})
    judged: list[Judged] = []
    states: collections.Counter[str] = collections.Counter()
    for tag in tags:
        train = [(t, s, a) for t, s, a in recs if t != tag and a.confidence is not None]
        cal = _fit([a.confidence or 0.0 for _t, _s, a in train], [s for _t, s, _a in train],
                   [f"{t} {k}" for k, (t, _s, _a) in enumerate(train)])
        states[cal.name if cal.used else cal.why.split(":")[0].split(" (")[0]] += 1
        judged += _judge([Judged(tag, s, a) for t, s, a in recs if t == tag], cal)
    print("\nPlant records, leave one tag out: each tag judged with the calibration fitted on "
          "the other tags' records as findings")
    print(f"folds: {len(tags)} tags; calibration per fold: "
          + ", ".join(f"{k} {n}" for k, n in sorted(states.items())))
    print(f"{'':<22} {'shipped':<44} leave-one-tag-out site calibration")
    print(f"{'records':<22} {_said(*_counts(judged, 'shipped')):<44} "
          f"{_said(*_counts(judged, 'site'))}")
    by_tag: dict[str, list[Judged]] = collections.defaultdict(list)
    for r in judged:
        by_tag[r.name].append(r)
    for which in ("shipped", "site"):
        called = {t: 2 * _counts(rs, which)[0] >= len(rs) for t, rs in by_tag.items()}
        sticky = {t: rs[0].sticky for t, rs in by_tag.items()}
        hits = sum(called[t] and sticky[t] for t in by_tag)
        print(f"{'tags (' + which + ')':<22} {sum(called.values())} called, {hits} sticky, "
              f"of {sum(sticky.values())} sticky tags and "
              f"{len(by_tag) - sum(sticky.values())} others")


def main() -> None:
    print("bench site_calibration: the site's own calibration of the confidence, fitted on "
          "the crew's findings (issue 39)")
    simulated_sites()
    plant_records()


if __name__ == "__main__":
    main()
