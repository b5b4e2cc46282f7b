"""What ``python -m lab decide`` prints (lab/training/decide.py): each candidate on the fold
that never saw a real record first (the plant records: sticky found, others called, the AUC
of its confidence, per tag), then the shared Tennessee Eastman records, the precision of
every fold and what each family of sources found; then the reliability of the shipped
confidence on the plant records held out beside the simulated windows."""

from __future__ import annotations

import collections
import itertools
from collections.abc import Sequence

import numpy as np

from stiction.diagnosis.call import shipped

from ..features.rows import Row
from .decide import PLANT, Scored, candidates

FAMILIES = (("TEP modes", "tep-mode"), ("realistic", "realistic"), ("scenarios", "scenarios"))


def auc(score: np.ndarray, y: np.ndarray) -> float:
    """P(a sticky window scores above a good one), ties half."""
    pos, neg = score[y], score[~y]
    if pos.size == 0 or neg.size == 0:
        return float("nan")
    gt = (pos[:, None] > neg[None, :]) + 0.5 * (pos[:, None] == neg[None, :])
    return float(gt.mean())


def _plant(rs: Sequence[Row], s: Scored, called: np.ndarray) -> tuple[int, int, int, int,
                                                                       int, int, int, int]:
    """(found, sticky, called, others) of every plant record (one a gate decided: not
    called), and the same per tag (a tag called when half its records are)."""
    at = {int(i): bool(c) for i, c in zip(s.idx, called, strict=True)}
    by: dict[str, list[bool]] = collections.defaultdict(list)
    sticky: dict[str, bool] = {}
    found = n = fp = m = 0
    for i, r in enumerate(rs):
        if r.source != PLANT:
            continue
        hit, is_sticky = at.get(i, False), r.cause_class == "stiction"
        by[r.run].append(hit)
        sticky[r.run] = is_sticky
        found, n = found + (hit and is_sticky), n + is_sticky
        fp, m = fp + (hit and not is_sticky), m + (not is_sticky)
    tags = {t: float(np.mean(v)) >= 0.5 for t, v in by.items()}
    return (found, n, fp, m, sum(h for t, h in tags.items() if sticky[t]), sum(sticky.values()),
            sum(h for t, h in tags.items() if not sticky[t]),
            sum(not v for v in sticky.values()))


def _fold(s: Scored, called: np.ndarray, name: str) -> tuple[int, int, int, int]:
    m = s.src == name
    return (int((called & m & s.y).sum()), int((m & s.y).sum()), int((called & m & ~s.y).sum()),
            int((m & ~s.y).sum()))


def report(rs: Sequence[Row], s: Scored) -> None:
    cands = candidates(s)
    plant = s.src == PLANT
    scored_sticky = int((plant & s.y).sum())
    print(f"== the fold that never saw a real record: the 80 plant records (decision fitted "
          f"without them, the network never saw them; {scored_sticky} of the 35 sticky "
          "records reach the decision, the others a gate decides) ==")
    print(f"  {'candidate':<22} {'sticky found':>12} {'others called':>13} {'AUC':>6}  "
          f"{'tags found':>10} {'tags called':>11}  {'TEP-shared':>10} {'called':>6}")
    for name, (called, conf) in cands.items():
        f, n, fp, m, tf, tn, tc, tm = _plant(rs, s, called)
        a = auc(conf[plant], s.y[plant])
        sf, sn, sc, sm = _fold(s, called, "tep-shared")
        print(f"  {name:<22} {f:>6} of {n:<3} {fp:>7} of {m:<3} {a:6.3f}  {tf:>5} of {tn:<2}"
              f" {tc:>6} of {tm:<2}  {sf:>5} of {sn:<2} {sc:>3} of {sm}")
    print("== every fold: precision of the calls (right / calls), held out; sticky found by "
          "family ==")
    folds = sorted(set(s.src.tolist()))
    for name, (called, _) in cands.items():
        precs = []
        for src in folds:
            m = s.src == src
            k, r = int((called & m).sum()), int((called & m & s.y).sum())
            precs.append(f"{src.replace('tep-mode', 'm')} {r}/{k}")
        total = called.sum()
        right = f"{(called & s.y).sum() / total:.0%}" if total else "-"
        found = ", ".join(
            f"{label} {int((called & s.y & np.char.startswith(s.src.astype(str), p)).sum())}"
            f"/{int((s.y & np.char.startswith(s.src.astype(str), p)).sum())}"
            for label, p in FAMILIES)
        print(f"  {name:<22} all {right:>4}; found {found}")
        print(f"  {'':<22} {', '.join(precs)}")
    _folds(s, cands["shipped"][0], cands["today"][0])
    _reliability(s, cands["shipped"][1], cands["shipped, site"][1])


def _folds(s: Scored, called: np.ndarray, before: np.ndarray) -> None:
    """Per fold, the shipped call: sticky found, precision, others called; today's in
    brackets."""
    print("== held out per fold, the shipped call (today's decision in brackets) ==")
    print(f"  {'source':<12} {'sticky found':>16} {'precision':>10}  others called")
    for src in sorted(set(s.src.tolist())):
        f, n, fp, m = _fold(s, called, src)
        bf, _, bfp, _ = _fold(s, before, src)
        prec = f"{f / (f + fp):.0%}" if f + fp else "-"
        print(f"  {src:<12} {f'{f}/{n} [{bf}]' if n else '-':>16} {prec:>10}  "
              f"{fp}/{m} [{bfp}]")


def _reliability(s: Scored, conf: np.ndarray, site: np.ndarray) -> None:
    at = shipped()
    bands = (0.0, at.band_low, 0.3, 0.5, at.threshold, 0.8, 0.9, 1.0001)
    plant = s.src == PLANT
    print("== reliability of the shipped confidence, held out: band, windows, share sticky ==")
    print(f"  {'band':<11} {'plant records':>15} {'plant, site':>15} {'the other folds':>17}")
    for lo, hi in itertools.pairwise(bands):
        cells = []
        for c, m in ((conf, plant), (site, plant), (conf, ~plant)):
            inb = m & (c >= lo) & (c < hi)
            n = int(inb.sum())
            cells.append(f"{n}: {s.y[inb].mean():.0%}" if n else "0")
        print(f"  {lo:.2f}-{min(hi, 1.0):.2f}  {cells[0]:>15} {cells[1]:>15} {cells[2]:>17}")
