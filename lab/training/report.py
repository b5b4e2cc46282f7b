"""What ``python -m lab train`` prints of the held-out scores: the threshold's trade-off,
every fold's sticky found and calls beside the weighted vote's, the reliability of the
scores; and the vote itself, the baseline, from a row's features."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stiction.diagnosis import combine
from stiction.diagnosis.features import NAMES, TEST_OF

from ..features.rows import Row
from .fit import folds, reliability

TESTS = tuple(dict.fromkeys(TEST_OF[n] for n in NAMES if n.endswith(".vote")))
INDEX = {n: i for i, n in enumerate(NAMES)}


def vote(x: np.ndarray) -> float:
    """The confidence of the weighted vote analyze used before the learned decision
    (stiction.diagnosis.combine), from the tests' votes in ``x``: the baseline."""
    tests = [t for t in TESTS if not np.isnan(x[INDEX[f"{t}.vote"]])]
    return combine.confidence_of(tests, [int(x[INDEX[f"{t}.vote"]]) for t in tests])


def _votes(rs: Sequence[Row], p: dict[int, float]) -> dict[int, float]:
    """The vote on every held-out window (each has its features)."""
    return {i: vote(x) for i in p if (x := rs[i].x) is not None}


def tradeoff(rs: Sequence[Row], p: dict[int, float]) -> None:
    """Held out, all folds: the stiction threshold against precision and what is found."""
    fams = ("tep", "realistic", "plant", "scenarios")
    print("threshold trade-off, held out: precision (all folds), sticky found per family; "
          "the vote first (the baseline)")
    votes = _votes(rs, p)
    for t in (-1.0, 0.7, 0.8, 0.85, 0.9, 0.93, 0.95, 0.97):
        tp = fp = 0
        found: dict[str, list[int]] = {f: [0, 0] for f in fams}
        for i, q in p.items():
            r = rs[i]
            score = votes[i] >= combine.STICTION_CONFIDENCE if t < 0 else q >= t
            sticky, called = r.cause_class == "stiction", bool(score)
            tp += called and sticky
            fp += called and not sticky
            fam = "tep" if r.source.startswith("tep-mode") else r.source
            if sticky and fam in found:
                found[fam][0] += called
                found[fam][1] += 1
        prec = tp / (tp + fp) if tp + fp else float("nan")
        name = "vote" if t < 0 else f"{t:.2f}"
        print(f"  {name:>4}: precision {prec:5.0%} ({fp} wrong calls); found " + ", ".join(
            f"{f} {a}/{b}" for f, (a, b) in found.items()))


def report(rs: Sequence[Row], p: dict[int, float], hi: float) -> None:
    tradeoff(rs, p)
    print(f"held out, leave one source out (stiction at >= {hi:.3f}):")
    print(f"  {'source':<12} {'sticky found':>14} {'precision':>10}  other causes called "
          "(the vote in brackets)")
    before = folds(rs, _votes(rs, p), combine.STICTION_CONFIDENCE)
    for s, f in folds(rs, p, hi).items():
        b = before[s]
        found = f"{f['found']}/{f['sticky']} [{b['found']}]" if f["sticky"] else "-"
        prec = f"{f['right'] / f['calls']:.0%}" if f["calls"] else "-"
        causes = ", ".join(f"{c} {f['called'][c]}/{n} [{b['called'][c]}]"
                           for c, n in f["of"].items())
        print(f"  {s:<12} {found:>14} {prec:>10}  {causes}")
    print("reliability, held out: score bin, windows, share sticky")
    for a, n, share in reliability(rs, p):
        print(f"  {a:.1f}-{a + 0.1:.1f}  {n:6d}  " + (f"{share:5.0%}" if n else "-"))
