"""Cycle switching points of PV: where each valve jump starts to show.

He & Wang (2014) section 3.2 need, for the PV fit, the onset of each exponential (or ramp),
not just one peak and one valley per cycle; they augment PeakFinder (Yoder 2011) with robust
spline smoothing (Garcia 2010) and a least-squares fit. Our version, in three passes:

1. **Extrema.** PV is block-averaged to about 48 points per period and smoothed robustly
   (:func:`stiction._smooth.smooth`, GCV-chosen); peaks and valleys with a prominence of at
   least 30 % of the smoothed range, at least a quarter period apart, alternating.
2. **Departures.** The first guess of each onset is where the smoothed PV leaves the
   extremum's plateau (falls 5 % of the swing below a peak, or rises above a valley).
3. **Onsets.** With a valve held between jumps, PV in each half cycle is exactly
   ``a + b exp(-(t - t_k)/tau)`` for a first-order self-regulating process (whatever came
   before), and ``a + b (t - t_k)`` for an integrator. ``tau`` is fitted once over all
   half cycles (bounded scalar search; the amplitudes are linear), then each onset is
   re-searched with those curves and placed, to a fraction of a sample, where the fitted
   curves of its two half cycles meet.

The result also carries the per-half-cycle fits: the steady state ``a`` (self-regulating) or
the slope ``b`` (integrating), from which :mod:`stiction._quantify` takes the jump size.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize, signal

from ._segments import closed_rss, exp_basis, sums2
from ._smooth import smooth
from ._validate import FloatArray

__all__ = ["Switches", "departures", "find_switches", "fitted_curve"]

POINTS_PER_PERIOD = 48
PROMINENCE = 0.3


@dataclasses.dataclass(frozen=True)
class Switches:
    """PV switching points (fractional sample positions) and the half-cycle fits.

    Half cycle ``k`` runs from ``onsets[k]`` to ``onsets[k + 1]`` and is fitted by
    ``a[k] + b[k] g(t - onsets[k])``, ``g`` the decaying exponential (self-regulating: ``a``
    is the steady state) or the ramp ``t - onsets[k]`` (integrating: ``b`` is the slope per
    sample). ``rss[k]`` and ``count[k]`` are that fit's residual sum of squares and size.
    """

    onsets: FloatArray
    a: FloatArray
    b: FloatArray
    rss: FloatArray
    count: FloatArray
    tau: float | None  # samples; None for an integrating process


def _extrema(z: FloatArray, period: float) -> np.ndarray:
    """Alternating peaks and valleys of the smoothed ``z`` (indices), at least a quarter
    period apart and with a prominence of 30 % of its range."""
    span = float(np.percentile(z, 98) - np.percentile(z, 2))
    dist = max(1, int(period / 4))
    pk, _ = signal.find_peaks(z, prominence=PROMINENCE * span, distance=dist)
    vl, _ = signal.find_peaks(-z, prominence=PROMINENCE * span, distance=dist)
    idx = np.concatenate((pk, vl))
    kind = np.concatenate((np.ones(pk.size), -np.ones(vl.size)))
    order = np.argsort(idx)
    idx, kind = idx[order], kind[order]
    # keep alternation: of two neighbours of one kind keep the more extreme
    keep_idx: list[int] = []
    keep_kind: list[float] = []
    for i, k in zip(idx.tolist(), kind.tolist(), strict=True):
        if keep_kind and keep_kind[-1] == k:
            if k * z[i] > k * z[keep_idx[-1]]:
                keep_idx[-1] = i
            continue
        keep_idx.append(i)
        keep_kind.append(k)
    return np.asarray(keep_idx, dtype=np.intp)


def departures(x: FloatArray, period: float) -> np.ndarray:
    """Where PV leaves each extremum's plateau: for each peak (valley), the last sample
    before the next extremum (or the window end) that is still within 5 % of the swing of
    the peak (valley) value, on the smoothed signal. A first guess of each onset, a little
    late by construction and refined by the model fit."""
    m = max(1, int(period // POINTS_PER_PERIOD))
    nb = x.size // m
    if nb < 8:
        return np.empty(0, dtype=np.intp)
    z, _ = smooth(x[: nb * m].reshape(nb, m).mean(axis=1), robust=True)
    ext = _extrema(z, period / m)
    out = []
    for k, e in enumerate(ext.tolist()):
        nxt = int(ext[k + 1]) if k + 1 < ext.size else nb - 1
        seg = z[e : nxt + 1]
        sign = 1.0 if k + 1 >= ext.size or z[e] > z[nxt] else -1.0
        swing = abs(float(z[e] - z[nxt])) if k + 1 < ext.size else abs(float(z[e] - z[ext[k - 1]]))
        near = np.flatnonzero(sign * (z[e] - seg) <= 0.05 * swing)
        if k + 1 >= ext.size and near[-1] == seg.size - 1:
            break  # PV never leaves the last plateau: no onset in the window
        out.append((e + int(near[-1])) * m + m // 2)
    return np.asarray(out, dtype=np.intp)


def _segment_sums(
    y: FloatArray, bounds: np.ndarray, refs: FloatArray, tau: float | None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Fit a + b g on each [bounds[k,0], bounds[k,1]); returns a, b, rss, count."""
    idx = np.concatenate([np.arange(i, j) for i, j in bounds])
    seg = np.repeat(np.arange(bounds.shape[0]), bounds[:, 1] - bounds[:, 0])
    starts = np.concatenate(([0], np.cumsum(bounds[:, 1] - bounds[:, 0])[:-1]))
    t_rel = idx - refs[seg]
    g = t_rel if tau is None else np.exp(-np.clip(t_rel / tau, -50.0, 700.0))
    sums = np.add.reduceat(sums2(g, y[idx]), starts, axis=1)
    r, a, b = closed_rss(sums)
    return a, b, r, sums[0]


def _fit_tau(y: FloatArray, bounds: np.ndarray, refs: FloatArray, period: float) -> float:
    """Common time constant (samples) of the exponentials of all half cycles."""
    idx = np.concatenate([np.arange(i, j) for i, j in bounds])
    seg_id = np.concatenate([np.full(j - i, k) for k, (i, j) in enumerate(bounds)])
    starts = np.concatenate(([0], np.cumsum(bounds[:, 1] - bounds[:, 0])[:-1]))
    t_rel = idx - refs[seg_id]
    yy = y[idx]
    n_k = np.add.reduceat(np.ones_like(yy), starts)
    sy = np.add.reduceat(yy, starts)
    syy = np.add.reduceat(yy * yy, starts)

    def total(log_tau: float) -> float:
        g = np.exp(-t_rel / math.exp(log_tau))
        sg = np.add.reduceat(g, starts)
        sgg = np.add.reduceat(g * g, starts)
        syg = np.add.reduceat(yy * g, starts)
        det = n_k * sgg - sg * sg
        ok = det > 1e-12 * n_k * n_k
        fit = np.where(
            ok,
            (sy * (sgg * sy - sg * syg) + syg * (n_k * syg - sg * sy)) / np.where(ok, det, 1.0),
            sy * sy / n_k,
        )
        # trimmed: the worst quarter of the half cycles (a misplaced switch, a double
        # jump) must not drag the time constant
        per = np.sort((syy - fit) / n_k)
        return float(np.sum(per[: max(1, (3 * per.size + 3) // 4)]))

    res = optimize.minimize_scalar(
        total, bounds=(math.log(0.2), math.log(20.0 * period)), method="bounded",
        options={"xatol": 1e-3},
    )
    return math.exp(float(res.x))


def _refine(
    y: FloatArray, onsets: FloatArray, tau: float | None, reach: int, guard: int
) -> FloatArray:
    """Re-search each onset within +-reach with the model curves; fractional result."""
    n = y.size
    out = onsets.astype(np.float64).copy()
    c_int = np.round(onsets).astype(np.intp)
    for k, c in enumerate(c_int.tolist()):
        lo = int(c_int[k - 1]) + guard if k > 0 else max(0, c - 3 * reach)
        hi = int(c_int[k + 1]) - guard if k + 1 < c_int.size else min(n, c + 3 * reach)
        c_lo, c_hi = max(lo + 3, c - reach), min(hi - 3, c + reach)
        if c_hi <= c_lo:
            continue
        # left sums are prefix sums from ``lo``, right sums suffix sums to ``hi``: an
        # exponential basis evaluated before its reference time grows huge, and sums of
        # differences of such would swamp the fit
        ref_l = float(onsets[k - 1]) if k > 0 else float(lo)
        cands = np.arange(c_lo, c_hi)
        t_l = np.arange(lo, c_hi, dtype=np.float64)
        t_r = np.arange(c_lo, hi, dtype=np.float64)
        s_l = np.cumsum(sums2(exp_basis(t_l, ref_l, tau)[:, 1], y[lo:c_hi]), axis=1)
        s_r = np.cumsum(sums2(exp_basis(t_r, float(c_lo), tau)[:, 1], y[c_lo:hi])[:, ::-1],
                        axis=1)[:, ::-1]
        r_l, a_l, b_l = closed_rss(s_l[:, cands - lo - 1])
        r_r, a_r, b_r = closed_rss(s_r[:, cands - c_lo])
        best = int(np.argmin(r_l + r_r))
        cb = int(cands[best])
        out[k] = _meet(np.array([a_l[best], b_l[best]]), ref_l,
                       np.array([a_r[best], b_r[best]]), float(c_lo), tau=tau, near=float(cb))
    return out


def _meet(cl: FloatArray, ref_l: float, cr: FloatArray, ref_r: float, *, tau: float | None,
          near: float) -> float:
    """Where the left and right fitted curves cross, within two samples of ``near``."""
    grid = near + np.linspace(-2.0, 1.0, 31)
    fl = exp_basis(grid, ref_l, tau) @ cl
    fr = exp_basis(grid, ref_r, tau) @ cr
    d = fl - fr
    sc = np.flatnonzero(np.signbit(d[1:]) != np.signbit(d[:-1]))
    if sc.size == 0:
        return near
    i = int(sc[np.argmin(np.abs(grid[sc] - near))])
    a, b = d[i], d[i + 1]
    return float(grid[i] + (grid[i + 1] - grid[i]) * (a / (a - b) if a != b else 0.5))


def find_switches(pv: FloatArray, period: float, *, integrating: bool) -> Switches | None:
    """PV switching points and half-cycle fits, or None when fewer than three are found."""
    kinks = departures(pv, period)
    if kinks.size < 3:
        return None
    scale = float(np.std(pv)) or 1.0
    y = (pv - float(np.mean(pv))) / scale
    guard = max(2, round(0.02 * period))
    tau: float | None = None
    if not integrating:
        bounds = np.column_stack((kinks[:-1] + guard, kinks[1:] - guard))
        bounds = bounds[bounds[:, 1] - bounds[:, 0] >= 6]
        if bounds.shape[0] == 0:
            return None
        tau = _fit_tau(y, bounds, bounds[:, 0].astype(np.float64) - guard, period)
    onsets = _refine(y, kinks.astype(np.float64), tau, reach=max(2 * guard + 2, int(period / 6)),
                     guard=guard)
    if not integrating:
        c = np.floor(onsets).astype(np.intp)
        bounds = np.column_stack((c[:-1] + 2, c[1:]))
        ok = bounds[:, 1] - bounds[:, 0] >= 6
        if ok.any():
            tau = _fit_tau(y, bounds[ok], onsets[:-1][ok], period)
        onsets = _refine(y, onsets, tau, reach=3, guard=1)
    c = np.floor(onsets).astype(np.intp)
    bounds = np.column_stack((c[:-1] + 1, c[1:] + 1))
    a, b, r, cnt = _segment_sums(y, bounds, onsets[:-1], tau)
    mean = float(np.mean(pv))
    return Switches(onsets, a * scale + mean, b * scale, r * scale * scale, cnt, tau)


def fitted_curve(sw: Switches, n: int) -> FloatArray:
    """The fitted PV between the first and last switching point (NaN elsewhere)."""
    out = np.full(n, np.nan)
    for k in range(sw.a.size):
        i, j = int(np.floor(sw.onsets[k])) + 1, min(n, int(np.floor(sw.onsets[k + 1])) + 1)
        t = np.arange(i, j, dtype=np.float64)
        out[i:j] = exp_basis(t, float(sw.onsets[k]), sw.tau) @ np.array([sw.a[k], sw.b[k]])
    return out
