"""Which confidence keeps its meaning on real loops (issue 36, item 3), measured on the
records the network never saw: each method's plant-record AUC, its calls at the threshold
chosen on simulation alone (90 % precise on the held-out simulated windows) and its
reliability table beside the simulated one.

Methods (stiction/diagnosis/site.py implements them in numpy):

- ``raw``: the ensemble's score as trained;
- ``platt``: a scale and offset on the logit fitted on held-out simulation (monotone: the
  ranking and the calls at a threshold chosen on simulation do not change, the meaning of
  a score does);
- ``coral-<target>`` / ``std-<target>``: the features aligned (full covariance or
  per-feature) from the target's statistics onto the simulation's, then the last layer;
  targets: ``batch`` (the scored records themselves, unlabelled: a batch of files or a
  gateway's loops), ``factory`` (another plant's loops: the two unlabelled factory loops);
- ``em``: Platt, then the site's share of sticky windows by EM (Saerens et al. 2002) on
  the scored batch (the simulation's share counted as ``site.PRIOR_WEIGHT`` windows);
- ``coral-batch+em``: both;
- ``coral-batch@em``: the site's share of sticky windows by EM first, then CORAL towards
  the simulation's features mixed at that share (sticky and good windows' statistics
  apart, stiction/diagnosis/site.py ``mixture``), so the site's many or few sticky valves
  are not aligned away; ``std-batch@em`` the same per feature;
- ``band``: an abstention band on the Platt score: ``stiction`` from the 90 %-precise
  threshold, ``no_stiction`` below the highest score under which at most 5 % of the
  simulated windows are sticky, ``undetermined`` between.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from stiction.diagnosis import site

from . import metrics, net

PRECISION = 0.9


@dataclasses.dataclass
class Scored:
    """Per ensemble member: the trained model and its features on every set."""

    models: list[Any]
    feats: list[dict[str, np.ndarray]]

    def logits(self, name: str, align: Callable[[int, np.ndarray], np.ndarray] | None = None
               ) -> np.ndarray:
        out = []
        for i, (m, f) in enumerate(zip(self.models, self.feats, strict=True)):
            x = f[name] if align is None else align(i, f[name])
            out.append(net.head(m, x))
        return np.asarray(np.mean(out, axis=0), dtype=np.float64)


def fit_platt(z: np.ndarray, y: np.ndarray, iterations: int = 50) -> tuple[float, float]:
    """Logistic regression of ``y`` on the logit ``z`` (Newton's method)."""
    a, b = 1.0, 0.0
    for _ in range(iterations):
        p = metrics.sigmoid(a * z + b)
        g = np.array([np.sum((p - y) * z), np.sum(p - y)])
        w = p * (1 - p) + 1e-9
        h = np.array([[np.sum(w * z * z), np.sum(w * z)], [np.sum(w * z), np.sum(w)]])
        step = np.linalg.solve(h + 1e-9 * np.eye(2), g)
        a, b = a - float(step[0]), b - float(step[1])
        if np.abs(step).max() < 1e-10:
            break
    return a, b


def _aligner(s: Scored, target: str, diagonal: bool, test: str, *,
             share: float | None = None, ys: np.ndarray | None = None
             ) -> Callable[[int, np.ndarray], np.ndarray]:
    """CORAL of member ``i``'s features towards the simulated ones (mixed at ``share`` of
    sticky windows when given: ``ys`` the simulated labels)."""
    def align(i: int, f: np.ndarray) -> np.ndarray:
        sim = s.feats[i]["sim"]
        if share is None or ys is None:
            src = site.SiteStats.of(sim)
        else:
            src = site.mixture(site.SiteStats.of(sim[ys == 1]), site.SiteStats.of(sim[ys == 0]),
                               share)
        tgt = site.SiteStats.of(s.feats[i][test if target == "batch" else target])
        return site.coral(f, tgt, src, diagonal=diagonal)
    return align


@dataclasses.dataclass(frozen=True)
class Outcome:
    method: str
    auc: float
    found: int
    sticky: int
    called: int
    others: int
    undetermined: tuple[int, int] | None  # (sticky, others) in the band
    reliability: list[tuple[float, float, int, float]]
    threshold: float
    prior: float | None = None


def methods(s: Scored, test: str, y: np.ndarray, ys: np.ndarray) -> list[Outcome]:
    """Every method on the set ``test`` (its labels ``y``; ``ys`` the simulated held-out
    windows' labels)."""
    z_sim = s.logits("sim")
    a, b = fit_platt(z_sim, ys)
    prior = float(ys.mean())
    out = []

    def add(name: str, p_test: np.ndarray, p_sim: np.ndarray, band: float | None = None,
            est: float | None = None) -> None:
        t = metrics.threshold_for_precision(p_sim, ys, PRECISION)
        found, sticky, called, others = metrics.calls(p_test, y, t)
        und = None
        if band is not None:
            mid = (p_test >= band) & (p_test < t)
            und = (int((mid & (y == 1)).sum()), int((mid & (y == 0)).sum()))
        out.append(Outcome(name, metrics.auc(p_test, y), found, sticky, called, others, und,
                           metrics.reliability(p_test, y), t, est))

    raw_sim, raw = metrics.sigmoid(z_sim), metrics.sigmoid(s.logits(test))
    add("raw", raw, raw_sim)
    cal_sim, cal = site.platt(z_sim, a, b), site.platt(s.logits(test), a, b)
    add("platt", cal, cal_sim)
    for target in ("batch", "factory"):
        for diagonal, label in ((False, "coral"), (True, "std")):
            al = _aligner(s, target, diagonal, test)
            add(f"{label}-{target}", site.platt(s.logits(test, al), a, b), cal_sim)
    em, share = site.label_shift(cal, prior, prior_weight=site.PRIOR_WEIGHT)
    add("em", em, cal_sim, est=share)
    al = _aligner(s, "batch", False, test)
    em2, share2 = site.label_shift(site.platt(s.logits(test, al), a, b), prior,
                                   prior_weight=site.PRIOR_WEIGHT)
    add("coral-batch+em", em2, cal_sim, est=share2)
    for diagonal, label in ((False, "coral"), (True, "std")):
        al = _aligner(s, "batch", diagonal, test, share=share, ys=ys)
        add(f"{label}-batch@em", site.platt(s.logits(test, al), a, b), cal_sim, est=share)
    lo = _low_band(cal_sim, ys)
    add("band", cal, cal_sim, band=lo)
    return out


def _low_band(p: np.ndarray, y: np.ndarray, share: float = 0.05) -> float:
    """The highest score under which at most ``share`` of the simulated windows are
    sticky."""
    order = np.argsort(p)
    frac = np.cumsum(y[order]) / np.arange(1, p.size + 1)
    ok = np.flatnonzero(frac <= share)
    return float(p[order][ok[-1]]) if ok.size else 0.0


def table(outcomes: Sequence[Outcome], sim_rel: list[tuple[float, float, int, float]]
          ) -> list[str]:
    lines = [f"  {'method':<16}{'AUC':>6}  {'threshold':>9}  found  called  undetermined"]
    for o in outcomes:
        und = "" if o.undetermined is None else f"{o.undetermined[0]} sticky, " \
            f"{o.undetermined[1]} others"
        est = "" if o.prior is None else f"  (site share {o.prior:.2f})"
        lines.append(f"  {o.method:<16}{o.auc:6.3f}  {o.threshold:9.3f}  {o.found:>2}/{o.sticky}"
                     f"  {o.called:>3}/{o.others}  {und}{est}")
    lines.append("  reliability (score band: windows, share sticky) simulated | " +
                 " | ".join(o.method for o in outcomes if o.method in SHOWN))
    for k, (lo, hi, n, share) in enumerate(sim_rel):
        row = [f"{n:>5} {share:4.0%}" if n else f"{n:>5}   - "]
        for o in outcomes:
            if o.method in SHOWN:
                _, _, m, sh = o.reliability[k]
                row.append(f"{m:>3} {sh:4.0%}" if m else f"{m:>3}   - ")
        lines.append(f"  {lo:.1f}-{hi:.1f}  " + " | ".join(row))
    return lines


SHOWN = ("platt", "coral-batch", "em", "coral-batch@em", "std-batch@em")
