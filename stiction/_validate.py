"""Argument checks shared by the public functions (raise ParameterError naming the argument)."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import ParameterError

FloatArray = NDArray[np.float64]


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


def order_statistics(x: NDArray[np.floating[Any]], ks: set[int]) -> dict[int, float]:
    """The ``k``-th smallest value (0-based) of a 1-D array without NaN, for each ``k`` in
    ``ks`` (each < ``x.size``).

    One kth per partition: numpy selects a single kth with SIMD, but several with a scalar
    introselect whose branches, on data it has not just seen, cost five to seven times as
    much (as ``np.median`` pays for an even count). Largest ``k`` first, each partition on
    the smaller values left of the last one; a ``k`` just below the last one is the maximum
    of those."""
    out: dict[int, float] = {}
    head = x
    exact = True  # head holds exactly the head.size smallest values, none used yet
    for k in sorted(ks, reverse=True):
        if exact and k == head.size - 1:
            out[k] = float(head.max())
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
    p = np.partition(a, h, axis=-1)
    if a.shape[-1] % 2:
        return np.asarray(p[..., h])
    return np.asarray((p[..., :h].max(axis=-1) + p[..., h]) / 2.0)


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


def as_float_array(name: str, value: ArrayLike) -> FloatArray:
    """``value`` as a float64 array (0-d for scalars); non-numeric input names ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, f"must be numeric, was {value!r}") from exc
    return arr


def finite(name: str, value: ArrayLike) -> FloatArray:
    arr = as_float_array(name, value)
    if not np.isfinite(arr).all():
        raise ParameterError(name, f"must be finite, was {_show(value)}")
    return arr


def non_negative(name: str, value: ArrayLike) -> FloatArray:
    arr = finite(name, value)
    if (arr < 0).any():
        raise ParameterError(name, f"must be >= 0, was {_show(value)}")
    return arr


def positive(name: str, value: ArrayLike) -> FloatArray:
    arr = finite(name, value)
    if np.any(arr <= 0):
        raise ParameterError(name, f"must be > 0, was {_show(value)}")
    return arr


def positive_scalar(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, f"must be a number, was {value!r}") from exc
    if not math.isfinite(v) or v <= 0:
        raise ParameterError(name, f"must be > 0, was {value!r}")
    return v


def _show(value: ArrayLike) -> str:
    arr = np.asarray(value)
    if arr.ndim == 0:
        return repr(arr.item())
    bad = arr[~np.isfinite(arr) | (arr < 0)] if arr.dtype.kind == "f" else arr
    return f"an array containing {bad.flat[0] if bad.size else arr.flat[0]!r}"


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
    peak = float(np.abs(x).max())
    if peak == 0.0:
        return f"{name} is constant"
    y = x / peak
    t, tt = centred_time(n)
    y = y - y.mean()
    y = y - (dot(t, y) / tt) * t
    span = float(np.abs(y).max())
    if not span > FLAT:
        return f"{name} is constant"
    return np.asarray(y / span, dtype=np.float64)
