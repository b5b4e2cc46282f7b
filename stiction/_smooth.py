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

import math

import numpy as np
from scipy import fft, optimize

from ._validate import FloatArray

__all__ = ["smooth"]

_BISQUARE_C = 4.685


def _lambda2(n: int) -> FloatArray:
    lam = -2.0 + 2.0 * np.cos(np.arange(n) * math.pi / n)
    return np.asarray(lam * lam)


def _gcv_s(dct_y: FloatArray, lam2: FloatArray) -> float:
    """The ``s`` minimising GCV(s) = (RSS/n) / (1 - tr(H)/n)^2 (searched on log10 s)."""
    n = dct_y.size

    def gcv(log_s: float) -> float:
        gamma = 1.0 / (1.0 + 10.0**log_s * lam2)
        rss = float(np.sum((dct_y * (gamma - 1.0)) ** 2))
        tr = float(np.sum(gamma))
        return rss / n / max(1.0 - tr / n, 1e-12) ** 2

    res = optimize.minimize_scalar(gcv, bounds=(-6.0, 12.0), method="bounded",
                                   options={"xatol": 0.05})
    return float(10.0 ** res.x)


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
        s_ = _gcv_s(dct_y, lam2) if s is None else s
        z = fft.idct(dct_y / (1.0 + s_ * lam2), norm="ortho")
        return np.asarray(z), s_

    # weighted / robust: Garcia's iteration, started from a linear interpolation
    idx = np.arange(n)
    good = w0 > 0
    z = np.interp(idx, idx[good], y[good]) if good.any() else np.zeros(n)
    w = w0.copy()
    s_ = 1.0 if s is None else s
    for step in range(robust_steps + 1 if robust else 1):
        for _ in range(max_iter):
            dct_r = fft.dct(w * (y_f - z) + z, norm="ortho")
            if s is None:  # GCV on the gap-filled, re-weighted data (as Garcia's code does)
                s_ = _gcv_s(dct_r, lam2)
            z_new = np.asarray(fft.idct(dct_r / (1.0 + s_ * lam2), norm="ortho"))
            change = float(np.linalg.norm(z_new - z)) / max(float(np.linalg.norm(z_new)), 1e-300)
            z = z_new
            if change < tol:
                break
        if robust and step < robust_steps:
            r = (y_f - z)[good]
            mad = float(np.median(np.abs(r - np.median(r))))
            if mad <= 0:
                break
            u = np.zeros(n)
            u[good] = r / (1.4826 * mad * math.sqrt(max(1.0 - _leverage(s_), 1e-6)))
            bis = np.where(np.abs(u) < _BISQUARE_C, (1.0 - (u / _BISQUARE_C) ** 2) ** 2, 0.0)
            w = w0 * bis
    return z, s_
