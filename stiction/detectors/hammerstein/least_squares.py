"""PV fitted through each valve candidate: a first-order lag (or an integrator) and a dead
time, gain, offset and drift in closed form, over all candidates at once."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from ..._validate import FloatArray
from ...signal.arrays import dot, mean, median

__all__ = [
    "PRODUCT_SIZE",
    "STICKY_MAX_LAG",
    "Target",
    "effective_n",
    "fit_rows",
    "masked_min",
    "period_spread",
    "process_path",
    "rel",
    "responses",
]

STICKY_MAX_LAG = 8  # the process path's dead time stays under 0.4 period
PRODUCT_SIZE = 300_000  # multiply-adds per matrix product (see _product)


@dataclasses.dataclass(frozen=True)
class Target:
    """The fitted PV with its lagged cross-product matrix and nuisance sums (offset, drift)
    for each dead time."""

    lags: np.ndarray
    cross: FloatArray  # (m, 2 * nlags): target and time, shifted by each lag
    n: FloatArray
    st: FloatArray
    stt: FloatArray
    sv: FloatArray
    svt: FloatArray
    det: FloatArray  # of the offset-and-drift normal equations (1 where singular)
    svv_c: FloatArray  # variance sum after removing offset and drift
    svv_d: FloatArray  # svv_c, 1 where 0 (the divisor of the residual shares)

    @classmethod
    def build(cls, v: FloatArray, lags: np.ndarray) -> Target:
        m = v.size
        t = np.arange(m, dtype=np.float64) - 0.5 * (m - 1)
        jj = np.arange(m)[:, None] + lags[None, :]
        ok = jj < m
        jc = np.minimum(jj, m - 1)
        cross = np.concatenate((np.where(ok, v[jc], 0.0), np.where(ok, t[jc], 0.0)), axis=1)
        # suffix sums of v, t, t^2, v t and v^2 (column d: the sum over [m - d, m)), in one pass
        suffix = np.zeros((5, m + 1))
        np.array((v, t, t * t, v * t, v * v))[:, ::-1].cumsum(axis=1, out=suffix[:, 1:])
        k = m - lags
        n = k.astype(np.float64)
        sv, st, stt, svt, svv = suffix[:, k]
        det = n * stt - st * st
        det = np.where(det > 0, det, 1.0)
        svv_c = svv - _proj((n, st, stt, det), sv, svt, sv, svt)
        return cls(lags, cross, n, st, stt, sv, svt, det, svv_c, np.where(svv_c > 0, svv_c, 1.0))

    def proj(self, a1: FloatArray, at: FloatArray, b1: FloatArray, bt: FloatArray) -> FloatArray:
        """The part of the cross sum of a and b that offset and drift explain."""
        return _proj((self.n, self.st, self.stt, self.det), a1, at, b1, bt)

    def fit(self, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Residual share of variance and gain of ``target ~ g y(t - lag) + c + b t`` for each
        row of ``y`` and each lag: arrays (rows, lags)."""
        m = y.shape[1]
        # sums over [0, m - lag): the whole row less a short tail
        width = int(np.maximum.reduce(self.lags)) if self.lags.size else 0
        y2 = y * y
        # the tails' sums of y and y^2 (column d: the last d samples), in one pass
        tails = np.zeros((2, y.shape[0], width + 1))
        np.array((y[:, m - width :], y2[:, m - width :]))[..., ::-1].cumsum(
            axis=2, out=tails[..., 1:])
        tail = tails[..., self.lags]
        sy = np.add.reduce(y, axis=1)[:, None] - tail[0]
        syy = np.add.reduce(y2, axis=1)[:, None] - tail[1]
        c = _product(y, self.cross)
        nl = self.lags.size
        syv, syt = c[:, :nl], c[:, nl:]
        syy_c = syy - self.proj(sy, syt, sy, syt)
        syv_c = syv - self.proj(sy, syt, self.sv, self.svt)
        ok = syy_c > 1e-9 * np.maximum(syy, 1e-300)
        g = np.where(ok, syv_c / np.where(ok, syy_c, 1.0), 0.0)
        rss = np.maximum(self.svv_c - g * syv_c, 0.0)
        return rss / self.svv_d, g


def _proj(nuisance: tuple[FloatArray, FloatArray, FloatArray, FloatArray], a1: FloatArray,
          at: FloatArray, b1: FloatArray, bt: FloatArray) -> FloatArray:
    """:meth:`Target.proj` from the nuisance sums ``(n, st, stt, det)``."""
    n, st, stt, det = nuisance
    return np.asarray((stt * a1 * b1 - st * (a1 * bt + at * b1) + n * at * bt) / det)


def _product(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a @ b`` in blocks of at most ``PRODUCT_SIZE`` multiply-adds: small products stay
    on one thread (OpenBLAS hands larger ones to its threads, which on a loaded two-core
    machine costs milliseconds for a product of microseconds)."""
    rows = max(1, PRODUCT_SIZE // max(a.shape[1] * b.shape[1], 1))
    if a.shape[0] <= rows:
        return np.asarray(a @ b)
    return np.concatenate([a[i : i + rows] @ b for i in range(0, a.shape[0], rows)])


def responses(vp: FloatArray, period: float, integrating: bool,
               taus: FloatArray) -> FloatArray:
    """The process model's response to each valve row, for each time constant: shape (taus,
    rows, samples); one time constant for integrating processes (whose target is PV's
    first difference)."""
    if integrating:
        return np.asarray(0.5 * (vp[:, 1:] + vp[:, :-1]))[None]
    out = np.empty((taus.size, *vp.shape))
    for y, tf in zip(out, taus, strict=True):
        a = math.exp(-1.0 / max(tf * period, 1e-3))
        y[:], _ = signal.lfilter([1.0 - a], [1.0, -a], vp, axis=1, zi=vp[:, :1] * a)
    return out


def fit_rows(target: Target, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Residual shares and gains of the responses ``ys`` (taus, rows, samples): shape
    (taus, rows, lags)."""
    share, g = target.fit(ys.reshape(-1, ys.shape[2]))
    return share.reshape(*ys.shape[:2], -1), g.reshape(*ys.shape[:2], -1)


def process_path(gain: FloatArray, lags: np.ndarray, sigma: float) -> np.ndarray:
    """Fits that go through the process: a gain of the sign negative feedback needs and a
    dead time under ``STICKY_MAX_LAG``; none when the controller's sign is unknown."""
    short = (lags <= STICKY_MAX_LAG)[None, None, :]
    return np.asarray((gain * sigma > 0) & short)


def masked_min(share: FloatArray, mask: np.ndarray) -> float:
    return float(np.min(np.where(mask, share, np.inf), initial=np.inf))


def rel(rss_a: float, rss_b: float) -> float:
    """Relative improvement of a fit with residual ``rss_a`` over one with ``rss_b``."""
    if not (math.isfinite(rss_a) and math.isfinite(rss_b)) or rss_b <= 0:
        return -math.inf
    return 1.0 - rss_a / rss_b


def period_spread(target: FloatArray, ys: FloatArray, share: FloatArray, mask: np.ndarray,
            *, lags: np.ndarray, per: float, sigma: float) -> float:
    """Period by period, the process path's best sticky valve against the linear valve
    with the same time constant and any dead time up to a period (any phase), each with its
    own gain (of the process path's sign) and offset in every period: the median of the
    relative improvements (-inf when either fit is missing)."""
    st = np.where(mask[:, 1:], share[:, 1:], np.inf)
    li = np.where(mask[:, :1], share[:, :1], np.inf)
    if not (math.isfinite(np.minimum.reduce(st, axis=None))
            and math.isfinite(np.minimum.reduce(li, axis=None))):
        return -math.inf
    i = np.unravel_index(int(st.argmin()), st.shape)
    j = np.unravel_index(int(li.argmin()), li.shape)
    start = int(np.maximum.reduce(lags))
    m = target.size
    v = target[start:]
    nb = max(1, round(v.size / per))
    edges = np.linspace(0, v.size, nb + 1).astype(np.intp)[:-1]
    ends = np.concatenate((edges[1:], [v.size]))
    cnt = (ends - edges).astype(np.float64)
    sv, svv = np.add.reduceat(v, edges), np.add.reduceat(v * v, edges)
    vvc = svv - sv * sv / cnt

    def rss(y: FloatArray) -> FloatArray:
        """Per period (columns), for each row of ``y``."""
        sy, syy = np.add.reduceat(y, edges, axis=1), np.add.reduceat(y * y, edges, axis=1)
        syv = np.add.reduceat(y * v, edges, axis=1)
        yyc, yvc = syy - sy * sy / cnt, syv - sy * sv / cnt
        g = np.where(yyc > 0, yvc / np.where(yyc > 0, yyc, 1.0), 0.0)
        g = np.where(g * sigma > 0, g, 0.0)
        return np.asarray(np.maximum(vvc - g * yvc, 0.0))

    # row 0 the sticky valve at its dead time, then the linear valve at every dead time
    lag_s = int(lags[i[2]])
    shifted = np.lib.stride_tricks.sliding_window_view(ys[j[0]][0], v.size)[start - lags]
    r = rss(np.vstack((ys[i[0]][i[1] + 1][start - lag_s : m - lag_s], shifted)))
    r_st, r_li = r[0], np.minimum.reduce(r[1:], axis=0)
    ok = r_li > 0
    if not ok.any():
        return -math.inf
    return median(1.0 - r_st[ok] / r_li[ok])


def _fit_residual(y: FloatArray, v: FloatArray, t: FloatArray) -> FloatArray:
    """Residual of ``v ~ g y + c + b t`` by least squares (y and t first made orthogonal
    to the constant and to each other: three small sums, no LAPACK call)."""
    tc = t - mean(t)
    vc = v - mean(v)
    stt = float(dot(tc, tc))
    bt = float(dot(vc, tc)) / stt if stt > 0 else 0.0
    yc = y - mean(y)
    yt = float(dot(yc, tc)) / stt if stt > 0 else 0.0
    yc = yc - yt * tc
    vc = vc - bt * tc
    syy = float(dot(yc, yc))
    g = float(dot(yc, vc)) / syy if syy > 1e-12 * max(float(dot(y, y)), 1e-300) else 0.0
    return np.asarray(vc - g * yc)


def effective_n(target: Target, y: FloatArray, lag: int) -> float:
    """Samples of the linear fit discounted for its residuals' lag-one autocorrelation."""
    m = y.shape[1]
    yy = y[0, : m - lag]
    t = np.arange(lag, m, dtype=np.float64)
    vv = target.cross[: m - lag, int((target.lags == lag).nonzero()[0][0])]
    r = _fit_residual(yy, vv, t)
    den = float(dot(r, r))
    rho = float(dot(r[1:], r[:-1])) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return float(r.size * (1.0 - rho) / (1.0 + rho))
