"""A site's own calibration of the confidence of stiction, fitted on the crew's findings.

The shipped decision (:mod:`stiction.diagnosis.model`) was fitted on a development corpus; at
a plant whose valves, friction and sampling differ, its confidence may rank the valves right
and still sit too high or too low against its thresholds. Once the crew has checked enough
valves, the site's findings say how it reads there. The recalibration is Cox's logistic
calibration (Cox 1958, "Two further applications of a model for binary regression",
Biometrika 45; Platt 1999's scaling applied to the logit of a probability), as a model is
updated for a new population (Steyerberg et al. 2004, "Validation and updating of predictive
logistic regression models", Stat. Med. 23):

    p = 1 / (1 + exp(-(scale x logit(c) + offset)))

``c`` the shipped confidence, ``p`` the site's. It is fitted by Newton's method on the
findings' log-likelihood with a Gaussian prior centred on the shipped map (scale 1, and no
shift of the log-odds at the findings' mean logit; strength :data:`PRIOR`, about one
finding's worth): a few findings move the map a little, many move it far, and findings that
separate perfectly give a finite slope. (Platt's own
remedy, targets of (N+1)/(N+2) and 1/(N+2), caps p at 6/7 = 0.86 with 5 sticky findings,
under the 0.87 a call of stiction needs: every call would be withdrawn.) The map is monotone
(scale > 0), so the site's order of its valves is the shipped one; what it moves is which of
them the thresholds call.

The rule (:func:`fit_site`):

1. the findings with a confidence on their day; ``sticky`` where the crew found the valve
   sticking, not where it found it fine, a dead band or another fault;
2. a valve found sticking and not sticking on one day contradicts itself: both are dropped
   (and named);
3. at least :data:`MIN_EACH` (5) of each kind, else the shipped calibration, "too few";
4. a fitted scale above 0, else the shipped calibration: at this site the valves found fine
   score as high as the sticky ones, so the findings contradict the confidence itself;
5. held out, the site's fit must predict the findings better than the shipped one (log loss
   of each finding predicted by a fit without it: leave one out up to :data:`LOO_MAX`
   findings, :data:`FOLDS`-fold beyond), else the shipped calibration: "it reads this site
   as well"; and its held-out calls (at the stiction threshold) must be no less precise on
   the findings than the shipped ones, else the shipped calibration: a calibration that
   reads the findings better on the whole but calls worse is not put in force.

It is pure: arrays in, a :class:`SiteCalibration` out. :func:`recalibrate` applies one to an
assessment: the confidence becomes the site's, a ``stiction`` call the site reads under the
threshold is withdrawn (``undetermined``, or ``no_stiction`` at or under its threshold, the
size with it), ``no_stiction`` and ``undetermined`` trade places across ``no_stiction_at``;
a call is never made that the analysis did not make (a call needs a test that says stiction
and a size: the analysis' own evidence gate), nor one changed that the valve's measured
travel decided.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._assessment import Assessment, Verdict
from .._validate import FloatArray

__all__ = ["FOLDS", "LOO_MAX", "MIN_EACH", "PRIOR", "Scores", "SiteCalibration", "fit_site",
           "platt_fit", "recalibrate", "shipped"]

MIN_EACH = 5
"""Findings of each kind (sticky, not sticky) before a site's calibration is fitted."""
PRIOR = 1.0
"""Strength of the prior on the scale - 1 and the shift of the log-odds at the findings'
mean logit: a Gaussian of variance 1 / PRIOR each."""
LOO_MAX = 400
FOLDS = 20
_EPS = 1e-6


def shipped() -> tuple[float, float]:
    """The shipped decision's thresholds ``(stiction_at, no_stiction_at)``."""
    from ..diagnosis import model  # noqa: PLC0415  (the decision's data: read on first use)

    m = model.load()
    return m.stiction_at, m.no_stiction_at


def _logit(c: FloatArray) -> FloatArray:
    x = np.clip(c, _EPS, 1.0 - _EPS)
    return np.asarray(np.log(x) - np.log1p(-x))


def _sigmoid(z: FloatArray) -> FloatArray:
    return np.asarray(np.exp(-np.logaddexp(0.0, -z)))


def platt_fit(x: ArrayLike, y: ArrayLike, *, prior: float = PRIOR) -> tuple[float, float]:
    """``(scale, offset)`` maximising the log-likelihood of ``y`` (0/1) under
    ``sigmoid(scale x + offset)`` with the prior of the module doc, centred on the findings:
    with ``m`` the mean of ``x``, on ``scale - 1`` and on the shift ``offset + (scale - 1) m``
    of the log-odds at ``m`` (so that a steeper map needs no large offset to keep its centre).
    Newton's method, each step halved until the objective falls (Lin, Lin & Weng 2007, "A note
    on Platt's probabilistic outputs for support vector machines", Mach. Learn. 68)."""
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    m = float(xs.mean()) if xs.size else 0.0
    u = xs - m
    centre = np.array([1.0, m])  # (scale, log-odds at m) of the shipped map
    theta = centre.copy()

    def objective(t: FloatArray) -> float:
        z = t[0] * u + t[1]
        nll = float(np.sum(np.logaddexp(0.0, z) - ys * z))
        return nll + 0.5 * prior * float(np.sum((t - centre) ** 2))

    f = objective(theta)
    for _ in range(100):
        p = _sigmoid(theta[0] * u + theta[1])
        r = p - ys
        grad = np.array([np.dot(r, u), r.sum()]) + prior * (theta - centre)
        w = p * (1.0 - p)
        hess = np.array([[np.dot(w, u * u), np.dot(w, u)], [np.dot(w, u), w.sum()]])
        hess += (prior + 1e-12) * np.eye(2)
        step = np.linalg.solve(hess, grad)
        size = 1.0
        while size > 1e-10:
            new = theta - size * step
            fn = objective(new)
            if fn <= f + 1e-4 * size * float(np.dot(grad, -step)):
                break
            size /= 2.0
        else:
            break
        theta, gain, f = new, f - fn, fn
        if gain < 1e-12 * max(1.0, abs(f)):
            break
    return float(theta[0]), float(theta[1] - theta[0] * m)


@dataclasses.dataclass(frozen=True)
class Scores:
    """How a calibration reads a set of findings: mean log loss and Brier score of its
    probabilities, and its calls at the threshold (``calls``, of which ``hits`` sticky;
    ``sticky`` in all)."""

    log_loss: float
    brier: float
    calls: int
    hits: int
    sticky: int

    @property
    def precision(self) -> float | None:
        return self.hits / self.calls if self.calls else None

    @property
    def recall(self) -> float | None:
        return self.hits / self.sticky if self.sticky else None

    @classmethod
    def of(cls, p: FloatArray, y: FloatArray, threshold: float) -> Scores:
        q = np.clip(p, _EPS, 1.0 - _EPS)
        loss = float(np.mean(-(y * np.log(q) + (1.0 - y) * np.log1p(-q)))) if y.size else 0.0
        called = p >= threshold
        return cls(loss, float(np.mean((p - y) ** 2)) if y.size else 0.0,
                   int(called.sum()), int((called & (y > 0.5)).sum()), int((y > 0.5).sum()))


@dataclasses.dataclass(frozen=True)
class SiteCalibration:
    """A site's calibration, or why the shipped one stays (``used`` False). ``sticky`` and
    ``good``: the findings used of each kind; ``dropped``: the keys of contradicting
    findings left out; ``site`` and ``shipped``: each calibration's scores on the findings
    (the site's held out), None when nothing was fitted; ``stiction_at``: the threshold
    the calls were counted at."""

    used: bool
    why: str
    scale: float = 1.0
    offset: float = 0.0
    sticky: int = 0
    good: int = 0
    dropped: tuple[str, ...] = ()
    site: Scores | None = None
    shipped: Scores | None = None
    stiction_at: float = 0.87

    @property
    def findings(self) -> int:
        return self.sticky + self.good

    @property
    def name(self) -> str:
        """``site`` or ``shipped``: the calibration in force."""
        return "site" if self.used else "shipped"

    def apply(self, confidence: float) -> float:
        """The site's confidence for the shipped ``confidence`` (itself when not used)."""
        if not self.used or not math.isfinite(confidence):
            return confidence
        z = self.scale * float(_logit(np.array([confidence]))[0]) + self.offset
        return float(_sigmoid(np.array([z]))[0])

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["dropped"] = list(self.dropped)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SiteCalibration:
        """Inverse of :meth:`to_dict`, every field's type and range checked (ValueError on
        anything else: it may come from a file)."""
        if set(data) != {f.name for f in dataclasses.fields(cls)}:
            raise ValueError(f"calibration: fields {sorted(data)}")
        d = dict(data)
        if not isinstance(d["used"], bool) or not isinstance(d["why"], str) \
                or len(d["why"]) > 2000:
            raise ValueError("calibration: used must be true/false, why a text")
        for key in ("scale", "offset", "stiction_at"):
            d[key] = _checked(d[key], key, 1e6)
        for key in ("sticky", "good"):
            d[key] = int(_checked(d[key], key, 1e9, whole=True))
        for key in ("site", "shipped"):
            if d[key] is not None:
                if not isinstance(d[key], dict) or set(d[key]) != set(_SCORE_FIELDS):
                    raise ValueError(f"calibration: {key} is not a set of scores")
                d[key] = Scores(**{k: _checked(v, f"{key}.{k}", 1e9,
                                               whole=k in ("calls", "hits", "sticky"))
                                   for k, v in d[key].items()})
        if not isinstance(d["dropped"], list) or len(d["dropped"]) > 100_000 or \
                not all(isinstance(k, str) for k in d["dropped"]):
            raise ValueError("calibration: dropped must be a list of texts")
        d["dropped"] = tuple(d["dropped"])
        cal = cls(**d)
        if cal.used and cal.scale <= 0:
            raise ValueError("calibration: a scale in force must be above 0")
        return cal


_SCORE_FIELDS = tuple(f.name for f in dataclasses.fields(Scores))


def _checked(x: Any, where: str, bound: float, *, whole: bool = False) -> Any:
    """A finite number within +-``bound`` (``whole``: an integer >= 0), as it is."""
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) \
            or abs(x) > bound:
        raise ValueError(f"calibration: {where} is not a number within {bound:g}")
    if whole and (int(x) != x or x < 0):
        raise ValueError(f"calibration: {where} is not a count")
    return int(x) if whole else float(x)


def fit_site(confidence: ArrayLike, sticky: ArrayLike, *, keys: Sequence[str] | None = None,
             min_each: int = MIN_EACH, stiction_at: float = 0.87,
             prior: float = PRIOR) -> SiteCalibration:
    """The site's calibration from its findings (module doc): per finding the shipped
    confidence on its day and whether the valve was found sticking; ``keys`` (a valve and
    a day) find the findings that contradict each other."""
    c = np.asarray(confidence, dtype=np.float64)
    y = np.asarray(sticky, dtype=bool)
    if c.shape != y.shape or c.ndim != 1:
        raise ValueError("confidence and sticky must be 1-D and of one length")
    keep = np.isfinite(c)
    dropped: list[str] = []
    if keys is not None:
        seen: dict[str, set[bool]] = {}
        for k, s, ok in zip(keys, y.tolist(), keep.tolist(), strict=True):
            if ok:
                seen.setdefault(k, set()).add(bool(s))
        dropped = sorted(k for k, kinds in seen.items() if len(kinds) > 1)
        keep &= np.array([k not in dropped for k in keys], dtype=bool)
    c, y = c[keep], y[keep]
    n1, n0 = int(y.sum()), int((~y).sum())
    said = "" if not dropped else (f"; {len(dropped)} finding(s) that contradict another of "
                                   f"their valve and day left out ({', '.join(dropped[:3])}"
                                   f"{', ...' if len(dropped) > 3 else ''})")
    base: dict[str, Any] = {"sticky": n1, "good": n0, "dropped": tuple(dropped),
                            "stiction_at": stiction_at}
    if n1 < min_each or n0 < min_each:
        return SiteCalibration(False, f"too few findings: {n1} sticky, {n0} not sticky; "
                               f"{min_each} of each needed{said}", **base)
    x, yf = _logit(c), y.astype(np.float64)
    scale, offset = platt_fit(x, yf, prior=prior)
    ship = Scores.of(c, yf, stiction_at)
    if scale <= 0:
        return SiteCalibration(False, "contradictory findings: the valves found not sticky "
                               "score as high as the sticky ones (the confidence does not "
                               f"separate them at this site){said}", shipped=ship, **base)
    held = _held_out(x, yf, prior)
    site = Scores.of(held, yf, stiction_at)
    if site.log_loss >= ship.log_loss:
        return SiteCalibration(False, f"the shipped calibration reads these findings as well "
                               f"(held-out log loss {site.log_loss:.3f} fitted, "
                               f"{ship.log_loss:.3f} shipped){said}", scale, offset,
                               site=site, shipped=ship, **base)
    if _less_precise(site, ship):
        return SiteCalibration(False, f"the fit's held-out calls are less precise than the "
                               f"shipped ones on these findings ({site.hits} of {site.calls} "
                               f"sticky against {ship.hits} of {ship.calls}){said}", scale,
                               offset, site=site, shipped=ship, **base)
    return SiteCalibration(True, f"fitted on {n1} sticky and {n0} not sticky findings "
                           f"(held-out log loss {site.log_loss:.3f}, shipped "
                           f"{ship.log_loss:.3f}){said}", scale, offset, site=site,
                           shipped=ship, **base)


def _less_precise(site: Scores, ship: Scores) -> bool:
    """Whether the site's held-out calls are less precise than the shipped ones (no calls
    where the shipped ones were all right counts as less: a site that loses its calls)."""
    if ship.calls == 0:
        return False
    if site.calls == 0:
        return ship.hits > 0
    return site.hits * ship.calls < ship.hits * site.calls


def _held_out(x: FloatArray, y: FloatArray, prior: float) -> FloatArray:
    """Each finding's probability from a fit without it (or without its fold)."""
    n = x.size
    folds = np.arange(n) if n <= LOO_MAX else np.arange(n) % FOLDS
    out = np.empty(n)
    for f in np.unique(folds):
        test = folds == f
        s, o = platt_fit(x[~test], y[~test], prior=prior)
        out[test] = _sigmoid(s * x[test] + o)
    return out


SIZE_FIELDS = {"fd": None, "fs": None, "jump": None, "fd_op": None, "fs_op": None,
               "cycles_used": 0, "multi_jump": False, "band": None, "band_op": None}
RECALIBRATED = (Verdict.STICTION, Verdict.UNDETERMINED, Verdict.NO_STICTION)


def recalibrate(a: Assessment, cal: SiteCalibration, *, stiction_at: float,
                no_stiction_at: float) -> Assessment:
    """``a`` under the site's calibration (module doc); the reason says which calibration
    it used. An assessment without a confidence, or of another verdict, is returned as it
    is."""
    if a.confidence is None or not math.isfinite(a.confidence) or a.verdict not in RECALIBRATED:
        return a
    c = a.confidence
    if not cal.used:
        return dataclasses.replace(a, reason=f"{_end(a.reason)} Calibration: shipped "
                                             f"({cal.why}).")
    p = cal.apply(c)
    said = (f"Calibration: this site's, from {cal.findings} findings: confidence {c:.2f} "
            f"reads {p:.2f} here.")
    new = a.verdict
    if a.position_use != "used":  # the valve's measured travel decided: it stands
        if a.verdict == Verdict.STICTION and p < stiction_at:
            new = Verdict.UNDETERMINED if p > no_stiction_at else Verdict.NO_STICTION
        elif a.verdict == Verdict.UNDETERMINED and p <= no_stiction_at:
            new = Verdict.NO_STICTION
        elif a.verdict == Verdict.NO_STICTION and p > no_stiction_at:
            new = Verdict.UNDETERMINED
    if new == a.verdict:
        return dataclasses.replace(a, confidence=p, reason=f"{_end(a.reason)} {said}")
    word = {Verdict.UNDETERMINED: "undetermined", Verdict.NO_STICTION: "not stiction"}[new]
    bar = (f"under the {stiction_at:.2f} a call of stiction needs" if a.verdict ==
           Verdict.STICTION else f"{'at or under' if p <= no_stiction_at else 'above'} "
           f"{no_stiction_at:.2f}")
    reason = (f"{word} at this site: the analysis said {a.verdict} at confidence {c:.2f}, "
              f"which this site's {cal.findings} findings read as {p:.2f}, {bar}. The "
              f"analysis: {_end(a.reason)} {said}")
    fields: dict[str, Any] = dict(SIZE_FIELDS) if a.verdict == Verdict.STICTION else {}
    return dataclasses.replace(a, verdict=new, confidence=p, reason=reason, **fields)


def _end(text: str) -> str:
    text = text.rstrip()
    return text if not text or text.endswith((".", "!", "?")) else text + "."
