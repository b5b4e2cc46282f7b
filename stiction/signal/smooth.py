"""Robust smoothing of 1-D data by penalised least squares with the DCT (Garcia 2010).

Garcia, "Robust smoothing of gridded data in one and higher dimensions with missing values",
Comput. Stat. Data Anal. 54 (2010) 1167-1178. The smoothed series ``z`` minimises
``||sqrt(W)(y - z)||^2 + s ||D z||^2`` with ``D`` the second-difference operator; with
reflective ends ``D^T D`` is diagonalised by the type-II DCT, so for unit weights
``z = IDCT(Gamma * DCT(y))`` with ``Gamma = 1 / (1 + s * Lambda^2)`` and
``Lambda_k = -2 + 2 cos(k pi / n)``. The smoothing parameter ``s`` minimises the generalised
cross-validation score, which in the DCT domain costs O(n) per trial ``s``. Weights (robust
bisquare re-weighting, or zero weights for missing samples) are handled by Garcia's
fixed-point iteration ``z <- IDCT(Gamma * DCT(W (y - z) + z))``.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import fft

from .._validate import FloatArray
from .arrays import dot, median

__all__ = ["smooth"]

_BISQUARE_C = 4.685


@functools.lru_cache(maxsize=8)
def _lambda2(n: int) -> FloatArray:
    """``Lambda_k^2`` for length ``n`` (read-only, cached: windows repeat their length)."""
    lam = -2.0 + 2.0 * np.cos(np.arange(n) * math.pi / n)
    out = np.asarray(lam * lam)
    out.flags.writeable = False
    return out


_STEP = 0.5
_LOG_S_GRID = np.arange(-6.0, 12.0 + 1e-9, _STEP)
_COARSE = 4  # the first search tries every 4th grid point (2 decades), then refines
_LAST = _LOG_S_GRID.size - 1
_BLOCK = 32768  # grid x frequency entries per pass of _gcv


@functools.lru_cache(maxsize=2)
def _shrinkage(n: int) -> FloatArray:
    """``q = s L / (1 + s L)`` for every ``s`` of the grid (rows) and every frequency of
    length ``n`` (read-only, cached: GCV needs it at every iteration and windows repeat
    their length; 37 x n values)."""
    q = np.multiply.outer(10.0**_LOG_S_GRID, _lambda2(n))
    np.divide(q, q + 1.0, out=q)
    q.flags.writeable = False
    return q


def _gcv_s(dct_y: FloatArray, near: float | None = None) -> float:
    """The ``s`` minimising GCV(s) = (RSS/n) / (1 - tr(H)/n)^2, searched on log10 s.

    GCV is evaluated on a grid of log10 s in [-6, 12] (step 0.5), and the minimum placed by
    a parabola through the best grid point and its neighbours (GCV is smooth in log s).
    Not every grid point is tried: without ``near`` every fourth one first, then the
    points within 1.5 decades of the best of those; with ``near`` (the previous
    iteration's ``s``) those within two decades of it. When the best point lands on the
    inner edge of such a stretch (the minimum lies further out), the rest of the grid on
    that side is tried too.
    """
    y2 = dct_y * dct_y
    if near is None:
        coarse = np.arange(0, _LAST + 1, _COARSE)
        centre = int(coarse[int(_gcv(y2, coarse).argmin())])
        idx = np.arange(max(0, centre - _COARSE + 1), min(_LAST, centre + _COARSE - 1) + 1)
    else:
        idx = (np.abs(_LOG_S_GRID - math.log10(near)) <= 2.0).nonzero()[0]
        if idx.size < 3:
            idx = np.arange(_LAST + 1)
    g = _gcv(y2, idx)
    i = int(g.argmin())
    if i == 0 and idx[0] > 0:  # the minimum lies further down: try the rest below
        more = np.arange(idx[0])
        idx, g = np.concatenate((more, idx)), np.concatenate((_gcv(y2, more), g))
        i = int(g.argmin())
    elif i == idx.size - 1 and idx[-1] < _LAST:  # further up
        more = np.arange(idx[-1] + 1, _LAST + 1)
        idx, g = np.concatenate((idx, more)), np.concatenate((g, _gcv(y2, more)))
        i = int(g.argmin())
    x = float(_LOG_S_GRID[idx[i]])
    if 0 < i < g.size - 1:
        g0, g1, g2 = float(g[i - 1]), float(g[i]), float(g[i + 1])
        den = g0 - 2.0 * g1 + g2
        if den > 0:
            x += _STEP * min(max(0.5 * (g0 - g2) / den, -0.5), 0.5)
    return float(10.0**x)


def _gcv(y2: FloatArray, grid: np.ndarray) -> FloatArray:
    """GCV at the grid points ``grid`` (indices into the log10 s grid) from the squared DCT
    coefficients ``y2``. With ``q = 1 - gamma = s L / (1 + s L)`` (:func:`_shrinkage`):
    RSS = sum q^2 y2, 1 - tr(H)/n = mean q.

    Blocks of frequencies at a time, in place and without BLAS: the whole grid x n matrix
    of a long window falls out of cache (and each such temporary is fresh memory from the
    OS), which made long windows superlinear; a threaded BLAS costs more than it saves on
    a busy CPU."""
    n = y2.size
    table = _shrinkage(n)
    cols = max(64, _BLOCK // grid.size)
    sum_q = np.zeros(grid.size)
    rss = np.zeros(grid.size)
    for k in range(0, n, cols):
        q = table[grid, k : k + cols]
        sum_q += np.add.reduce(q, axis=1)
        np.multiply(q, q, out=q)
        rss += np.einsum("gk,k->g", q, y2[k : k + cols])
    return np.asarray(rss / n / np.maximum(sum_q / n, 1e-12) ** 2)


def _leverage(s: float) -> float:
    """Average leverage of the 1-D smoother (Garcia 2010, eq for h in 1-D)."""
    q = math.sqrt(1.0 + 16.0 * s)
    return math.sqrt(1.0 + q) / (math.sqrt(2.0) * q)


def smooth(
    y: FloatArray,
    *,
    s: float | None = None,
    weights: FloatArray | None = None,
    robust: bool = False,
    robust_steps: int = 3,
    max_iter: int = 50,
    tol: float = 1e-4,
) -> tuple[FloatArray, float]:
    """Smooth ``y`` (1-D, finite where ``weights > 0``); returns ``(z, s)``.

    ``s`` fixed or chosen by GCV; ``weights`` in [0, 1] (0 marks a missing sample, whose
    value is ignored); ``robust`` re-weights ``robust_steps`` times with Tukey's bisquare on
    studentised residuals, so outliers do not pull the curve.
    """
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    if n < 3:
        return y.copy(), 0.0 if s is None else s
    lam2 = _lambda2(n)
    w0 = np.ones(n) if weights is None else np.clip(np.asarray(weights, dtype=np.float64), 0, 1)
    y_f = np.where(w0 > 0, y, 0.0)
    if weights is None and not robust:
        dct_y = fft.dct(y_f, norm="ortho")
        s_ = _gcv_s(dct_y) if s is None else s
        z = fft.idct(dct_y / (1.0 + s_ * lam2), norm="ortho")
        return np.asarray(z), s_

    # weighted / robust: Garcia's iteration, started from a linear interpolation
    idx = np.arange(n)
    good = w0 > 0
    all_good = bool(good.all())
    if all_good:
        z = y_f.copy()
    else:
        z = np.interp(idx, idx[good], y[good]) if good.any() else np.zeros(n)
    w = w0.copy()
    s_ = 1.0 if s is None else s
    s_searched = False
    for step in range(robust_steps + 1 if robust else 1):
        unit = bool(np.all(w == 1.0))  # unit weights: the first iteration is exact
        for _ in range(1 if unit else max_iter):
            dct_r = fft.dct(w * (y_f - z) + z, norm="ortho")
            if s is None:  # GCV on the gap-filled, re-weighted data (as Garcia's code does)
                s_ = _gcv_s(dct_r, near=s_ if s_searched else None)
                s_searched = True
            z_new = np.asarray(fft.idct(dct_r / (1.0 + s_ * lam2), norm="ortho"))
            if unit:
                z = z_new
                break
            dz = z_new - z
            change = math.sqrt(dot(dz, dz) / max(dot(z_new, z_new), 1e-300))
            z = z_new
            if change < tol:
                break
        if robust and step < robust_steps:
            r = y_f - z if all_good else (y_f - z)[good]
            mad = median(np.abs(r - median(r)))
            if mad <= 0:
                break
            scale = 1.4826 * mad * math.sqrt(max(1.0 - _leverage(s_), 1e-6))
            if all_good:
                u = r / scale
            else:
                u = np.zeros(n)
                u[good] = r / scale
            bis = np.where(np.abs(u) < _BISQUARE_C, (1.0 - (u / _BISQUARE_C) ** 2) ** 2, 0.0)
            w = w0 * bis
    return z, s_
