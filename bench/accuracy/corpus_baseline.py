"""Today's ``stiction.analyze`` on the development corpus: the "before" of issue 24.

``python -m bench corpus_baseline`` (after ``python -m lab corpus``) analyses every window
(``CORPUS_BASELINE_N=k``: at most k per source, view and cause class, drawn with a fixed
seed) as the gateway would, ``analyze(op, pv, ts=ts, process=process)``, and prints the
share called: ``stiction`` or ``valve_not_responding`` (as bench/accuracy/real_data.py counts them).
Tables: per source and cause class; the TEP windows per view; the TEP loops with a good
valve per cause (each disturbance, pooled over the modes). With tep-studio installed it
also reruns the reported failure (mode 1, seed 3, 48 h at 36 s, XMV 10 -> reactor
temperature, IDV 11 and IDV 14).
"""

from __future__ import annotations

import collections
import os
import time
from collections.abc import Callable, Sequence

import numpy as np

from lab.labels.corpus import Window, load_windows
from lab.sources import tep
from lab.windows.tep import settled
from stiction import analyze

CALLS = ("stiction", "valve_not_responding")


def _sample(windows: Sequence[Window], per_group: int | None) -> list[Window]:
    if per_group is None:
        return list(windows)
    groups: dict[tuple[str, str, str], list[Window]] = collections.defaultdict(list)
    for w in windows:
        groups[(w.source, w.view, w.cause_class)].append(w)
    rng = np.random.default_rng(24)
    out = []
    for _, ws in sorted(groups.items()):
        pick = rng.permutation(len(ws))[:per_group]
        out += [ws[i] for i in sorted(pick)]
    return out


def _table(title: str, windows: Sequence[Window], verdicts: dict[str, str],
           key: Callable[[Window], str], *, only_called: bool = False) -> None:
    print(f"\n  {title}")
    groups: dict[str, list[Window]] = collections.defaultdict(list)
    for w in windows:
        groups[key(w)].append(w)
    for label, ws in sorted(groups.items()):
        kinds = collections.Counter(verdicts[w.key] for w in ws)
        called = sum(kinds[c] for c in CALLS)
        if only_called and not called:
            continue
        print(f"    {label:<40} n={len(ws):>5}  called {called:>5} ({called / len(ws):6.1%})  "
              + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))


def reported_failure() -> None:
    """Mode 1, seed 3, 48 h, 36 s samples, XMV 10 -> reactor temperature (XMEAS 9), with
    IDV 11 (random cooling-water inlet temperature) and with IDV 14 (sticky valve, 2 %)."""
    try:
        start = settled("mode1")
    except ImportError:
        print("\n  reported failure: skipped (tep-studio not installed)")
        return
    print("\n  reported failure: mode 1, seed 3, 48 h, XMV 10 -> reactor temperature "
          "(onset 0.5 h)")
    j = [lp.name for lp in tep.LOOPS].index("XMV10")
    for name, idvs, bands in (("IDV 11", [(11, 1.0)], {}), ("IDV 14 (2 %)", [], {9: 2.0})):
        a = tep.run(start, 3, idvs, bands, onset_h=0.5, record_h=(0.0, 48.0))
        for label, first in (("all 48 h", 0), ("from 4.5 h", round(4.5 * 3600 / 1.8))):
            op, pv = a.op[first:, j][19::20], a.pv[first:, j][19::20]  # 36 s snapshots
            r = analyze(op, pv, ts=36.0)
            print(f"    {name:<13} {label:<11} {op.size} samples at 36 s: {r.verdict} "
                  f"({r.reason})")


def main() -> None:
    t0 = time.perf_counter()
    per_group = os.environ.get("CORPUS_BASELINE_N")
    windows = _sample(load_windows(), int(per_group) if per_group else None)
    if not any(w.source.startswith("tep-mode") for w in windows):
        print("corpus_baseline: no TEP windows (run python -m lab corpus first)")
    verdicts = {}
    t1 = time.process_time()
    for w in windows:
        verdicts[w.key] = str(analyze(w.op, w.pv, ts=w.ts, process=w.process).verdict)
    spent = time.process_time() - t1
    print(f"== today's analyze on the corpus: {len(windows)} windows, "
          f"{1000 * spent / max(len(windows), 1):.1f} ms each ==")
    _table("per source and cause class", windows, verdicts,
           lambda w: f"{w.source} {w.cause_class}")
    tep = [w for w in windows if w.source.startswith("tep-mode")]
    _table("TEP, per view and cause class", tep, verdicts,
           lambda w: f"{w.view} {w.ts:g} s {w.cause_class}")
    _table("TEP, sticky valves per IDV and band", [w for w in tep if w.sticky], verdicts,
           lambda w: f"{w.cause.split('+')[0]} {w.stiction_size:g} % {w.cause_class}")
    _table("TEP, good valves per cause (called only)", [w for w in tep if not w.sticky],
           verdicts, lambda w: f"{w.cause} {w.cause_class}", only_called=True)
    reported_failure()
    print(f"(corpus_baseline: {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
