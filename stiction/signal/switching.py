"""Cycle switching points of PV: where each valve jump starts to show.

He & Wang (2014) section 3.2 need, for the PV fit, the onset of each exponential (or ramp),
not just one peak and one valley per cycle; they augment PeakFinder (Yoder 2011) with robust
spline smoothing (Garcia 2010) and a least-squares fit. Our version, in three passes:

1. **Extrema.** PV is block-averaged to about 48 points per period and smoothed robustly
   (:func:`stiction.signal.smooth.smooth`, GCV-chosen, one bisquare re-weighting: it keeps
   outliers from making an extremum as the default three did, at half the passes; this is
   only the first guess, which the fits below refine); peaks and valleys with a prominence
   of at least 30 % of the smoothed range, at least a quarter period apart, alternating.
2. **Departures.** The first guess of each onset is where the smoothed PV leaves the
   extremum's plateau (falls 5 % of the swing below a peak, or rises above a valley).
3. **Onsets.** With a valve held between jumps, PV in each half cycle is exactly
   ``a + b exp(-(t - t_k)/tau)`` for a first-order self-regulating process (whatever came
   before), and ``a + b (t - t_k)`` for an integrator. ``tau`` is fitted once over all
   half cycles (bounded scalar search; the amplitudes are linear), then each onset is
   re-searched with those curves and placed, to a fraction of a sample, where the fitted
   curves of its two half cycles meet.

The result also carries the per-half-cycle fits: the steady state ``a`` (self-regulating) or
the slope ``b`` (integrating), from which :mod:`stiction.quantify.hewang` takes the jump size.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from .._validate import FloatArray
from .arrays import mean, percentiles, std
from .bounded import fminbound
from .segments import closed_rss, exp_basis, ragged, row_chunks
from .smooth import smooth

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
    p2, p98 = percentiles(z, (2.0, 98.0))
    span = float(p98 - p2)
    dist = max(1, int(period / 4))
    pk, _ = signal.find_peaks(z, prominence=PROMINENCE * span, distance=dist)
    vl, _ = signal.find_peaks(-z, prominence=PROMINENCE * span, distance=dist)
    idx = np.concatenate((pk, vl))
    kind = np.concatenate((np.ones(pk.size), -np.ones(vl.size)))
    order = idx.argsort()
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
    z, _ = smooth(np.add.reduce(x[: nb * m].reshape(nb, m), axis=1) / m, robust=True,
                  robust_steps=1)
    ext = _extrema(z, period / m)
    if ext.size == 0:
        return np.empty(0, dtype=np.intp)
    # per extremum: the stretch to the next one (the last: to the window end), the swing of
    # that stretch (the last: the swing before it), and which way PV leaves
    nxt = np.concatenate((ext[1:], [nb - 1]))
    ze, zn = z[ext], z[nxt]
    swing = np.abs(ze - zn)
    swing[-1] = abs(float(ze[-1] - z[ext[-2] if ext.size > 1 else ext[-1]]))
    sign = np.where(ze > zn, 1.0, -1.0)
    sign[-1] = 1.0
    idx, mask = ragged(ext, nxt - ext + 1)
    near = mask & (sign[:, None] * (ze[:, None] - z[idx]) <= (0.05 * swing)[:, None])
    pos = idx.shape[1] - 1 - near[:, ::-1].argmax(axis=1)  # last such sample
    keep = np.ones(ext.size, dtype=bool)
    keep[-1] = pos[-1] != nxt[-1] - ext[-1]  # PV never leaves the last plateau: no onset
    return np.asarray((ext + pos)[keep] * m + m // 2, dtype=np.intp)


def _decay(t: FloatArray, tau: float) -> FloatArray:
    """``exp(-t / tau)``, the exponent clipped to [-50, 700]: the decaying basis a time ``t``
    after its reference (before it, the basis grows)."""
    return np.asarray(np.exp(-np.minimum(np.maximum(t / tau, -50.0), 700.0)))


def _interval_sums(y: FloatArray, i: np.ndarray, j: np.ndarray, refs: FloatArray,
                   tau: float | None) -> FloatArray:
    """Sums (n, Sg, Sgg, Sy, Syg, Syy) of ``y ~ a + b g(t - refs[k])`` over each nonempty
    ``[i[k], j[k])``, as a (6, K) array: one flat pass, no padding."""
    lengths = j - i
    starts = np.concatenate(([0], lengths.cumsum()[:-1]))
    seg = np.repeat(np.arange(i.size), lengths)
    idx = np.arange(int(lengths.sum())) + (i - starts)[seg]
    t_rel = idx - refs[seg]
    g = t_rel if tau is None else _decay(t_rel, tau)
    yy = y[idx]
    out = np.empty((6, i.size))
    out[0] = lengths
    for row, v in enumerate((g, g * g, yy, yy * g, yy * yy), start=1):
        out[row] = np.add.reduceat(v, starts)  # row by row: long windows stay in cache
    return out


def _segment_sums(
    y: FloatArray, bounds: np.ndarray, refs: FloatArray, tau: float | None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Fit a + b g on each [bounds[k,0], bounds[k,1]); returns a, b, rss, count."""
    sums = _interval_sums(y, bounds[:, 0], bounds[:, 1], refs, tau)
    r, a, b = closed_rss(sums)
    return a, b, r, sums[0]


def _fit_tau(y: FloatArray, bounds: np.ndarray, refs: FloatArray, period: float) -> float:
    """Common time constant (samples) of the exponentials of all half cycles."""
    lengths = bounds[:, 1] - bounds[:, 0]
    starts = np.concatenate(([0], lengths.cumsum()[:-1]))
    seg_id = np.repeat(np.arange(lengths.size), lengths)
    idx = np.arange(int(lengths.sum())) + (bounds[:, 0] - starts)[seg_id]
    neg_t = -(idx - refs[seg_id])
    # references on whole samples (the first call's): the times are whole samples, a few
    # hundred distinct ones, and each evaluation takes their exponentials once (the same
    # numbers: exp of the same floats) and gathers them
    whole = refs.astype(np.intp)
    table: tuple[FloatArray, np.ndarray] | None = None
    if np.array_equal(whole, refs):
        t_int = idx - whole[seg_id]
        lo = int(t_int.min())
        table = -np.arange(lo, int(t_int.max()) + 1, dtype=np.float64), t_int - lo
    yy = y[idx]
    n_k = lengths.astype(np.float64)
    sy = np.add.reduceat(yy, starts)
    syy = np.add.reduceat(yy * yy, starts)
    tiny = 1e-12 * n_k * n_k
    mean_fit = sy * sy / n_k

    keep = max(1, (3 * lengths.size + 3) // 4)
    planes = np.empty((3, yy.size))  # g, g^2, y g: one reduceat for the three sums
    g, gg, yg = planes

    def total(log_tau: float) -> float:
        if table is None:
            np.divide(neg_t, math.exp(log_tau), out=g)
            np.exp(g, out=g)
        else:
            g[:] = np.exp(table[0] / math.exp(log_tau))[table[1]]
        np.multiply(g, g, out=gg)
        np.multiply(yy, g, out=yg)
        sg, sgg, syg = np.add.reduceat(planes, starts, axis=1)
        det = n_k * sgg - sg * sg
        ok = det > tiny
        num = sy * (sgg * sy - sg * syg) + syg * (n_k * syg - sg * sy)
        fit = num / det if ok.all() else np.where(ok, num / np.where(ok, det, 1.0), mean_fit)
        # trimmed: the worst quarter of the half cycles (a misplaced switch, a double
        # jump) must not drag the time constant
        per = (syy - fit) / n_k
        per.sort()
        return float(np.add.reduce(per[:keep]))

    log_tau = fminbound(total, math.log(0.2), math.log(20.0 * period), xtol=1e-3)
    return math.exp(log_tau)


def _basis(t: FloatArray, t0: FloatArray, tau: float | None) -> FloatArray:
    """The varying column of :func:`exp_basis` for a matrix of times, one reference per row."""
    d = t - t0[:, None]
    return d if tau is None else _decay(d, tau)


def _refine(
    y: FloatArray, onsets: FloatArray, tau: float | None, reach: int, guard: int
) -> FloatArray:
    """Re-search each onset within +-reach with the model curves; fractional result.

    Many onsets at once: the left curve is fitted over ``[lo, c)`` (from the previous
    onset), the right one over ``[c, hi)`` (to the next), for every candidate ``c`` in
    ``[c_lo, c_hi)``; the candidates of each onset are one row of a zero-padded matrix
    (padding adds zeros to every sum)."""
    n = y.size
    out = onsets.astype(np.float64).copy()
    c = np.rint(onsets).astype(np.intp)
    if c.size == 0:
        return out
    lo = np.empty_like(c)
    hi = np.empty_like(c)
    lo[1:] = c[:-1] + guard
    lo[0] = max(0, int(c[0]) - 3 * reach)
    hi[:-1] = c[1:] - guard
    hi[-1] = min(n, int(c[-1]) + 3 * reach)
    c_lo = np.maximum(lo + 3, c - reach)
    c_hi = np.minimum(hi - 3, c + reach)
    ks = (c_hi > c_lo).nonzero()[0]
    if ks.size == 0:
        return out
    lo, hi, c_lo, c_hi = lo[ks], hi[ks], c_lo[ks], c_hi[ks]
    # left sums are prefix sums from ``lo``, right sums suffix sums to ``hi``: an
    # exponential basis evaluated before its reference time grows huge, and sums of
    # differences of such would swamp the fit
    ref_l = np.where(ks > 0, onsets[np.maximum(ks - 1, 0)], lo.astype(np.float64))
    ref_r = c_lo.astype(np.float64)
    for sl in row_chunks(c_hi - c_lo):
        out[ks[sl]] = _refine_rows(y, (lo[sl], hi[sl], c_lo[sl], c_hi[sl]),
                                   (ref_l[sl], ref_r[sl]), tau)
    return out


def _refine_rows(y: FloatArray, ends: tuple[np.ndarray, ...],
                 refs: tuple[FloatArray, FloatArray], tau: float | None) -> FloatArray:
    """:func:`_refine` for a chunk of onsets (bounded so the matrices stay in cache).

    The sums over ``[lo, c_lo)`` and ``[c_hi, hi)`` are common to all candidates of an
    onset; only the stretch ``[c_lo, c_hi)`` needs cumulative sums (one zero-padded row per
    onset). Left and right fits are stacked (rows ``:k`` and ``k:``) so that each step is
    one array operation."""
    lo, hi, c_lo, c_hi = ends
    ref_l, ref_r = refs
    k = lo.size
    both = np.concatenate((ref_l, ref_r))
    bulk = _interval_sums(y, np.concatenate((lo, c_hi)), np.concatenate((c_lo, hi)), both, tau)
    lengths = c_hi - c_lo
    cand, mc = ragged(c_lo, lengths)
    t = cand.astype(np.float64)
    # planes g, g^2, y, y g, y^2 of the candidates (padding zero); the counts need no sums
    g = _basis(np.concatenate((t, t)), both, tau)
    m2 = np.concatenate((mc, mc))
    part = np.empty((5, *g.shape))
    np.multiply(g, m2, out=part[0])
    np.multiply(part[0], part[0], out=part[1])
    np.multiply(y[cand], mc, out=part[2, :k])
    part[2, k:] = part[2, :k]
    np.multiply(part[2], g, out=part[3])
    np.multiply(part[2], part[2], out=part[4])
    sums = np.empty((6, *g.shape))
    col = np.arange(g.shape[1])
    sums[0, :k] = np.minimum(col[None, :], lengths[:, None])
    sums[0, k:] = np.maximum(lengths[:, None] - col[None, :], 0)
    sums[1:, :k, 0] = 0.0
    part[:, :k, :-1].cumsum(axis=2, out=sums[1:, :k, 1:])  # left: over [c_lo, c)
    part[:, k:, ::-1].cumsum(axis=2, out=sums[1:, k:, ::-1])  # right: over [c, c_hi)
    sums += bulk[..., None]
    r, a, b = closed_rss(sums)
    best = np.where(mc, r[:k] + r[k:], np.inf).argmin(axis=1)
    rows = np.arange(k)
    near = cand[rows, best].astype(np.float64)
    return _meet((a[rows, best], b[rows, best], ref_l),
                 (a[rows + k, best], b[rows + k, best], ref_r), tau=tau, near=near)


def _meet(left: tuple[FloatArray, FloatArray, FloatArray],
          right: tuple[FloatArray, FloatArray, FloatArray], *, tau: float | None,
          near: FloatArray) -> FloatArray:
    """Where each pair of left and right fitted curves crosses, when that is within two
    samples before or one after ``near`` (else ``near`` itself). Each side is ``(a, b,
    ref)`` of the curve ``a + b g(t - ref)``. Their difference is ``A + B (t - near)`` for
    ramps and ``A + B exp(-(t - near) / tau)`` for exponentials (same tau): monotone, so
    the crossing is in closed form."""
    a_l, b_l, ref_l = left
    a_r, b_r, ref_r = right
    if tau is None:
        big_a = a_l - a_r + b_l * (near - ref_l) - b_r * (near - ref_r)
        big_b = b_l - b_r
        ok = big_b != 0
        step = -big_a / np.where(ok, big_b, 1.0)
    else:
        big_b = b_l * _decay(near - ref_l, tau) - b_r * _decay(near - ref_r, tau)
        ratio = (a_r - a_l) / np.where(big_b != 0, big_b, 1.0)
        ok = (big_b != 0) & (ratio > 0)
        step = -tau * np.log(np.where(ok, ratio, 1.0))
    ok &= (step >= -2.0) & (step <= 1.0)
    return np.asarray(np.where(ok, near + step, near))


def find_switches(pv: FloatArray, period: float, *, integrating: bool) -> Switches | None:
    """PV switching points and half-cycle fits, or None when fewer than three are found."""
    kinks = departures(pv, period)
    if kinks.size < 3:
        return None
    scale = std(pv) or 1.0
    centre = mean(pv)
    y = (pv - centre) / scale
    guard = max(2, round(0.02 * period))
    tau: float | None = None
    if not integrating:
        bounds = np.array((kinks[:-1] + guard, kinks[1:] - guard)).T
        bounds = bounds[bounds[:, 1] - bounds[:, 0] >= 6]
        if bounds.shape[0] == 0:
            return None
        tau = _fit_tau(y, bounds, bounds[:, 0].astype(np.float64) - guard, period)
    onsets = _refine(y, kinks.astype(np.float64), tau, reach=max(2 * guard + 2, int(period / 6)),
                     guard=guard)
    if not integrating:
        c = np.floor(onsets).astype(np.intp)
        bounds = np.array((c[:-1] + 2, c[1:])).T
        ok = bounds[:, 1] - bounds[:, 0] >= 6
        if ok.any():
            tau = _fit_tau(y, bounds[ok], onsets[:-1][ok], period)
        onsets = _refine(y, onsets, tau, reach=3, guard=1)
    # refining moves each onset on its own; two that cross (a fast ringing cycle whose
    # fitted curves meet out of order) would give a half cycle of negative length
    onsets = np.sort(onsets)
    onsets = onsets[np.concatenate(([True], onsets[1:] - onsets[:-1] >= 1.0))]
    if onsets.size < 3:
        return None
    c = np.floor(onsets).astype(np.intp)
    bounds = np.array((c[:-1] + 1, c[1:] + 1)).T
    a, b, r, cnt = _segment_sums(y, bounds, onsets[:-1], tau)
    return Switches(onsets, a * scale + centre, b * scale, r * scale * scale, cnt, tau)


def fitted_curve(sw: Switches, n: int) -> FloatArray:
    """The fitted PV between the first and last switching point (NaN elsewhere)."""
    out = np.full(n, np.nan)
    for k in range(sw.a.size):
        i, j = int(np.floor(sw.onsets[k])) + 1, min(n, int(np.floor(sw.onsets[k + 1])) + 1)
        t = np.arange(i, j, dtype=np.float64)
        out[i:j] = exp_basis(t, float(sw.onsets[k]), sw.tau) @ np.array([sw.a[k], sw.b[k]])
    return out
