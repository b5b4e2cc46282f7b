"""Keeping the shape network's score meaning the same at a site (issue 36, item 3): the
statistics of its features over the loops at hand, and what is done with them.

A network trained on simulation ranks real loops well but its scores shift there (a real
plant's noise, loads and historian move the features). The loops of one site, unlabelled,
are a free sample of that shift:

- :class:`SiteStats` holds the running count, mean and scatter of the penultimate features
  (:func:`stiction.diagnosis.shape.features`) over a site's windows: the files of one batch
  (``stiction analyze --manifest``) or a gateway's loops over its rounds. It updates one
  window or a batch at a time, merges, and turns into and from plain lists, so a gateway
  can persist it in its state file.
- :func:`coral` maps a window's features from the site's distribution onto the simulated
  one (CORAL, Sun, Feng and Saenko 2016, here the inverse direction: the network's last
  layer stays as trained and the site's features are whitened by the site's covariance and
  re-coloured by the simulation's). With few windows the site's covariance is shrunk towards
  the simulation's (``prior`` windows' worth), so a handful of loops moves the features
  only a little and a single window not at all; ``diagonal`` keeps per-feature means and
  SDs only (per-site standardisation).
- :func:`label_shift` re-estimates the share of sticky windows at the site by EM (Saerens,
  Latinne and Decaestecker 2002) and rescales calibrated posteriors to it.
- :func:`mixture` gives the simulation's statistics at a site's share of sticky windows
  (from the sticky and the good windows' statistics apart): a site with many sticky valves
  moves its features by that too, and aligning it to the simulation's own share (a few
  sticky windows in five) would take the sticky ones' features away with the shift.
- :func:`platt` maps a logit to a probability with a scale and an offset fitted on
  held-out simulation (temperature when the offset is 0).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from .._validate import FloatArray

__all__ = ["PRIOR_WEIGHT", "SiteStats", "coral", "label_shift", "mixture", "platt", "shifted"]

PRIOR_WEIGHT = 10.0
"""Windows' worth of the simulation's share of sticky windows in a site's EM estimate
(:func:`label_shift`): on subsets of 40 plant records drawn at 5-75 % sticky, 80-95 % of
the shape network's calls were right with it, 76-90 % without (lab/shape/README.md)."""


@dataclasses.dataclass(frozen=True)
class SiteStats:
    """Count ``n``, ``mean`` (d,) and ``scatter`` (d, d: the sum of outer products of the
    deviations from the mean) of feature vectors; :meth:`empty` to start."""

    n: int
    mean: FloatArray
    scatter: FloatArray

    @classmethod
    def empty(cls, dim: int) -> SiteStats:
        return cls(0, np.zeros(dim), np.zeros((dim, dim)))

    @classmethod
    def of(cls, feats: FloatArray) -> SiteStats:
        """The statistics of a batch (windows, d)."""
        f = np.atleast_2d(np.asarray(feats, dtype=np.float64))
        mu = f.mean(axis=0)
        d = f - mu
        return cls(f.shape[0], mu, d.T @ d)

    def update(self, feats: FloatArray) -> SiteStats:
        """With a window (d,) or a batch (windows, d) more."""
        return self.merge(SiteStats.of(feats))

    def merge(self, other: SiteStats) -> SiteStats:
        """Both sets of windows together (Chan et al.'s parallel update)."""
        if other.n == 0:
            return self
        if self.n == 0:
            return other
        n = self.n + other.n
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.n / n)
        scatter = self.scatter + other.scatter + np.outer(delta, delta) * (self.n * other.n / n)
        return SiteStats(n, mean, scatter)

    @property
    def cov(self) -> FloatArray:
        return self.scatter / max(self.n - 1, 1)

    def to_dict(self) -> dict[str, object]:
        """Plain lists and numbers (JSON, YAML, the gateway's state file)."""
        return {"n": self.n, "mean": self.mean.tolist(), "scatter": self.scatter.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, object]) -> SiteStats:
        mean = np.asarray(d["mean"], dtype=np.float64)
        scatter = np.asarray(d["scatter"], dtype=np.float64)
        n = d["n"]
        if not isinstance(n, int) or n < 0 or mean.ndim != 1 or \
                scatter.shape != (mean.size, mean.size) or not np.all(np.isfinite(scatter)):
            raise ValueError("site statistics: n a count, mean (d,), scatter (d, d), finite")
        return cls(n, mean, scatter)


def mixture(sticky: SiteStats, good: SiteStats, share: float) -> SiteStats:
    """The statistics of windows of which ``share`` are drawn like ``sticky`` and the rest
    like ``good`` (their means and covariances mixed; counted as both together)."""
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"share must lie in [0, 1], was {share!r}")
    d = sticky.mean - good.mean
    mean = share * sticky.mean + (1.0 - share) * good.mean
    cov = share * sticky.cov + (1.0 - share) * good.cov + share * (1.0 - share) * np.outer(d, d)
    n = sticky.n + good.n
    return SiteStats(n, mean, cov * max(n - 1, 1))


def _sqrt(c: FloatArray, inverse: bool) -> FloatArray:
    """The symmetric square root of a covariance (or of its inverse)."""
    w, v = np.linalg.eigh((c + c.T) / 2.0)
    w = np.maximum(w, 1e-9 * max(float(w.max()), 1e-12))
    return np.asarray((v * (w ** (-0.5 if inverse else 0.5))) @ v.T, dtype=np.float64)


def coral(feats: FloatArray, site: SiteStats, source: SiteStats, *, prior: float = 16.0,
          diagonal: bool = False, eps: float = 1e-3) -> FloatArray:
    """Features (d,) or (windows, d) of a site mapped onto the source's distribution (module
    doc). The site's mean and covariance are shrunk towards the source's by ``prior``
    windows' worth; ``eps`` times the mean variance is added to both covariances. A site
without windows leaves the features as they are."""
    f = np.asarray(feats, dtype=np.float64)
    if site.n == 0:
        return f.copy()
    n = float(site.n)
    w = n / (n + prior)
    mu = w * site.mean + (1.0 - w) * source.mean
    c_s = source.cov
    c_t = (site.scatter + prior * c_s) / max(n - 1.0 + prior, 1.0)
    dim = c_s.shape[0]
    ridge_s = eps * float(np.trace(c_s)) / dim * np.eye(dim)
    ridge_t = eps * float(np.trace(c_t)) / dim * np.eye(dim)
    if diagonal:
        scale = np.sqrt((np.diag(c_s) + np.diag(ridge_s)) / (np.diag(c_t) + np.diag(ridge_t)))
        return np.asarray((f - mu) * scale + source.mean, dtype=np.float64)
    a = _sqrt(c_t + ridge_t, inverse=True) @ _sqrt(c_s + ridge_s, inverse=False)
    return np.asarray((f - mu) @ a + source.mean, dtype=np.float64)


def platt(logit: FloatArray | float, scale: float, offset: float) -> FloatArray:
    """sigmoid(scale x logit + offset)."""
    z = scale * np.asarray(logit, dtype=np.float64) + offset
    return np.asarray(1.0 / (1.0 + np.exp(-np.clip(z, -60.0, 60.0))), dtype=np.float64)


def shifted(posteriors: FloatArray | float, source_prior: float, share: float) -> FloatArray:
    """Posteriors calibrated where the share of sticky windows was ``source_prior``, at a
    share of ``share`` (Bayes' rule: the odds times the ratio of the two priors' odds)."""
    p = np.asarray(posteriors, dtype=np.float64)
    a, b = share / source_prior, (1.0 - share) / (1.0 - source_prior)
    return np.asarray(a * p / (a * p + b * (1.0 - p)), dtype=np.float64)


def label_shift(posteriors: Sequence[float] | FloatArray, source_prior: float, *,
                prior_weight: float = 0.0, iterations: int = 100, tol: float = 1e-6
                ) -> tuple[FloatArray, float]:
    """Saerens et al.'s EM: posteriors calibrated where the share of sticky windows was
    ``source_prior``, rescaled to the share the site's windows imply; returns (the rescaled
    posteriors, that share). ``prior_weight`` counts the source's share as that many windows
    more (a maximum a posteriori estimate): a handful of windows moves the share little, and
    no window leaves it at the source's."""
    p = np.clip(np.asarray(posteriors, dtype=np.float64), 1e-9, 1.0 - 1e-9)
    if not 0.0 < source_prior < 1.0:
        raise ValueError(f"source_prior must lie in (0, 1), was {source_prior!r}")
    prior = source_prior

    def rescaled(share: float) -> FloatArray:
        return shifted(p, source_prior, share)

    q = p
    for _ in range(iterations):
        q = rescaled(prior)
        new = (float(q.sum()) + prior_weight * source_prior) / (q.size + prior_weight) \
            if q.size + prior_weight > 0 else source_prior
        new = float(np.clip(new, 1e-6, 1.0 - 1e-6))
        if abs(new - prior) < tol:
            break
        prior = new
    else:
        q = rescaled(prior)
    return q, prior
