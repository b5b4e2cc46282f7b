"""Least-squares fits of many intervals at once, by prefix sums.

For a basis ``X`` (n x p, p <= 3) and data ``y``, the normal equations of the fit of ``y``
on ``X`` over any interval ``[i, j)`` follow from cumulative sums of ``X_a X_b``, ``X_a y``
and ``y^2``; so the residual sum of squares of thousands of candidate intervals (all split
points of a change-point search) costs one pass over the data plus a batch of p x p solves.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray

__all__ = ["Prefix", "closed_rss", "exp_basis", "prefix", "ragged", "row_chunks", "rss"]

CHUNK = 4096
"""Entries of one zero-padded matrix of :func:`ragged` rows processed at a time."""


@dataclasses.dataclass(frozen=True)
class Prefix:
    xx: FloatArray  # (n + 1, p, p)
    xy: FloatArray  # (n + 1, p)
    yy: FloatArray  # (n + 1,)


def prefix(x: FloatArray, y: FloatArray) -> Prefix:
    """Prefix sums for the basis ``x`` (n x p) and data ``y`` (n)."""
    n, p = x.shape
    xx = np.zeros((n + 1, p, p))
    np.cumsum(x[:, :, None] * x[:, None, :], axis=0, out=xx[1:])
    xy = np.zeros((n + 1, p))
    np.cumsum(x * y[:, None], axis=0, out=xy[1:])
    yy = np.zeros(n + 1)
    np.cumsum(y * y, out=yy[1:])
    return Prefix(xx, xy, yy)


def rss(pre: Prefix, i: np.ndarray, j: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """Residual sum of squares and coefficients of the fit over each ``[i[k], j[k])``.

    A tiny ridge keeps degenerate intervals (a basis column that is constant there)
    solvable; their fit is then the minimum-norm one.
    """
    a = pre.xx[j] - pre.xx[i]
    b = pre.xy[j] - pre.xy[i]
    c = pre.yy[j] - pre.yy[i]
    p = a.shape[-1]
    scale = np.trace(a, axis1=-2, axis2=-1) / p
    ridge = (1e-10 * scale + 1e-300)[:, None, None] * np.eye(p)
    coef = np.linalg.solve(a + ridge, b[..., None])[..., 0]
    r = c - np.einsum("kp,kp->k", coef, b)
    return np.maximum(r, 0.0), coef


def exp_basis(t: FloatArray, t0: float, tau: float | None) -> FloatArray:
    """Columns (1, exp(-(t - t0)/tau)) of a first-order response after a step at ``t0``;
    ``tau=None`` gives (1, t - t0), the ramp of an integrating process."""
    g = t - t0 if tau is None else np.exp(-np.clip((t - t0) / tau, -50.0, 700.0))
    return np.column_stack((np.ones_like(t), g))


def closed_rss(s: FloatArray | tuple[FloatArray, ...]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """RSS and (a, b) of ``y ~ a + b g`` from the sums (n, Sg, Sgg, Sy, Syg, Syy) along
    axis 0 (or as six broadcastable arrays); a degenerate ``g`` (constant over the
    interval) falls back to ``y ~ a``."""
    n, sg, sgg, sy, syg, syy = s
    nsgg = n * sgg
    det = nsgg - sg * sg
    ok = det > 1e-12 * np.maximum(nsgg, 1e-300)
    num = n * syg - sg * sy
    b = np.divide(num, det, out=np.zeros(np.broadcast_shapes(num.shape, det.shape)), where=ok)
    a = (sy - b * sg) / np.maximum(n, 1.0)
    r = syy - a * sy - b * syg
    return np.maximum(r, 0.0), a, b


def ragged(starts: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index matrix ``(K, max(lengths))`` of the intervals ``[starts[k], starts[k] +
    lengths[k])`` and the mask of its valid entries (padding repeats ``starts[k]``)."""
    width = max(int(np.maximum.reduce(lengths)), 1) if lengths.size else 1
    off = np.arange(width)
    mask = off[None, :] < lengths[:, None]
    return starts[:, None] + np.where(mask, off[None, :], 0), mask


def row_chunks(lengths: np.ndarray, budget: int = CHUNK) -> list[slice]:
    """Consecutive row ranges whose padded matrices (rows x longest row) stay within
    ``budget`` entries (at least one row each). Row-wise fits done chunk by chunk keep their
    working set in cache: one matrix for the whole window made long windows superlinear."""
    out: list[slice] = []
    start, n = 0, lengths.size
    if n and int(np.maximum.reduce(lengths)) * n <= budget:  # the common case: one chunk
        return [slice(0, n)]
    while start < n:
        # a chunk's size with each further row: nondecreasing, so a binary search
        size = np.maximum.accumulate(lengths[start:]) * np.arange(1, n - start + 1)
        stop = start + max(1, int(np.searchsorted(size, budget, side="right")))
        out.append(slice(start, stop))
        start = stop
    return out or [slice(0, 0)]
