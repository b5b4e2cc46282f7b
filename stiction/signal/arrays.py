"""Array helpers of the hot paths: order statistics, medians and percentiles without numpy's
generic machinery (the same values, bit for bit), a BLAS-free inner product, the centred
time axis of a window and the unit-scaled detrended signal."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._validate import FloatArray

SORT_BELOW = 700
"""Values per order statistic below which :func:`order_statistics` sorts instead of
partitioning."""


@functools.lru_cache(maxsize=16)
def centred_time(n: int) -> tuple[FloatArray, float]:
    """Sample times about the window's centre and their sum of squares (read-only, cached:
    every test of a window removes straight lines from signals of its length)."""
    t = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
    t.flags.writeable = False
    return t, dot(t, t)


def dot(a: NDArray[np.floating[Any]], b: NDArray[np.floating[Any]]) -> float:
    """Inner product of two 1-D arrays without BLAS: a BLAS dot goes multi-threaded on long
    vectors, and on a busy (edge) CPU the thread hand-off costs more than the arithmetic
    (it made analyze() grow superlinearly with the window length)."""
    return float(np.einsum("i,i->", a, b))


def mean(x: NDArray[np.floating[Any]]) -> float:
    """``x.mean()`` of a non-empty 1-D array: the same value without its Python layer."""
    return float(np.add.reduce(x) / x.size)


def std(x: NDArray[np.floating[Any]]) -> float:
    """``x.std()`` of a non-empty 1-D array: the same value (the same sums in the same
    order) without its Python layers, which cost more than the arithmetic on a few thousand
    values."""
    n = x.size
    d = x - np.add.reduce(x) / n
    return math.sqrt(float(np.add.reduce(np.multiply(d, d, out=d)) / n))


def order_statistics(x: NDArray[np.floating[Any]], ks: set[int]) -> dict[int, float]:
    """The ``k``-th smallest value (0-based) of a 1-D array without NaN, for each ``k`` in
    ``ks`` (each < ``x.size``).

    One kth per partition: numpy selects a single kth with SIMD, but several with a scalar
    introselect whose branches, on data it has not just seen, cost five to seven times as
    much (as ``np.median`` pays for an even count). Largest ``k`` first, each partition on
    the smaller values left of the last one; a ``k`` just below the last one is the maximum
    of those.

    On a short array a sort is cheaper still (NumPy sorts with SIMD, and one call replaces
    a partition and a copy per ``k``): below ``SORT_BELOW`` values per ``k`` (measured: a
    sort of 3,600 values costs what four or six partitions do, of 751 values a third)."""
    if x.size < SORT_BELOW * len(ks):
        s = np.sort(x)
        return {k: float(s[k]) for k in ks}
    out: dict[int, float] = {}
    head = x
    exact = True  # head holds exactly the head.size smallest values, none used yet
    for k in sorted(ks, reverse=True):
        if exact and k == head.size - 1:
            out[k] = float(np.maximum.reduce(head))
            exact = False
        else:
            part = head.copy()
            part.partition(k)
            out[k] = float(part[k])
            head, exact = part[:k], True
    return out


def median(x: NDArray[np.floating[Any]]) -> float:
    """``np.median`` of a 1-D array without NaN (NaN when empty): the same value without
    its generic machinery (see :func:`order_statistics`)."""
    if x.size == 0:
        return float("nan")
    h = x.size // 2
    if x.size % 2:
        return order_statistics(x, {h})[h]
    s = order_statistics(x, {h - 1, h})
    return (s[h - 1] + s[h]) / 2.0


def medians(a: NDArray[np.floating[Any]]) -> FloatArray:
    """``np.median(a, axis=-1)`` of an array without NaN (rows not empty): the same values,
    one kth per partition (see :func:`order_statistics`)."""
    h = a.shape[-1] // 2
    p = a.copy()
    p.partition(h, axis=-1)
    if a.shape[-1] % 2:
        return np.asarray(p[..., h])
    return np.asarray((np.maximum.reduce(p[..., :h], axis=-1) + p[..., h]) / 2.0)


def percentiles(x: NDArray[np.floating[Any]], q: tuple[float, ...]) -> tuple[float, ...]:
    """``np.percentile(x, q)`` (its default linear method, bit for bit) of a non-empty 1-D
    array without NaN, from single-kth partitions (see :func:`order_statistics`), without
    the generic machinery."""
    n = x.size
    pos = [(n - 1) * (p / 100.0) for p in q]
    lo = [min(math.floor(v), n - 1) for v in pos]
    s = order_statistics(x, {*lo, *(min(i + 1, n - 1) for i in lo)})
    out = []
    for v, i in zip(pos, lo, strict=True):
        a, b = s[i], s[min(i + 1, n - 1)]
        g = v - i
        # numpy's lerp: from the nearer end
        out.append(b - (b - a) * (1.0 - g) if g >= 0.5 else a + (b - a) * g)
    return tuple(out)


FLAT = 1e-12
"""Detrended peak over raw peak below this: the signal is constant to float precision."""


def unit_detrended(x: NDArray[np.floating[Any]], *, name: str, min_samples: int
                   ) -> FloatArray | str:
    """``x`` with mean and straight line removed, scaled to unit peak (scaled first, so no
    unit or magnitude, 1e-300 or 1e300, reaches the arithmetic), or why it cannot be used:
    too short, non-finite, constant."""
    n = x.size
    if n < min_samples:
        return f"record too short to tell: {n} samples"
    if not np.isfinite(x).all():
        return f"{name} has non-finite samples"
    peak = float(np.maximum.reduce(np.abs(x)))
    if peak == 0.0:
        return f"{name} is constant"
    y = x / peak
    t, tt = centred_time(n)
    y = y - np.add.reduce(y) / n
    y = y - (dot(t, y) / tt) * t
    span = float(np.maximum.reduce(np.abs(y)))
    if not span > FLAT:
        return f"{name} is constant"
    return np.asarray(y / span, dtype=np.float64)
