"""Argument checks shared by the public functions (raise ParameterError naming the argument)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import ParameterError

FloatArray = NDArray[np.float64]


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


