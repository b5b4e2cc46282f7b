"""The arguments of :func:`stiction.analyze`, checked: a :class:`~stiction.ParameterError`
naming the argument and what is wrong with it, never a crash further in."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._errors import ParameterError
from .._validate import FloatArray

__all__ = ["PROCESSES", "along", "validate"]

PROCESSES = ("self-regulating", "integrating")


def _series(name: str, value: ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "must be a sequence of numbers") from exc
    if arr.ndim != 1:
        raise ParameterError(name, f"must be one-dimensional, has {arr.ndim} dimensions")
    return arr


def _scalar(name: str, value: Any, *, positive: bool = False, non_negative: bool = False,
            non_zero: bool = False) -> float:
    if isinstance(value, bool):
        raise ParameterError(name, f"must be a number, was {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, f"must be a number, was {value!r}") from exc
    if not math.isfinite(v):
        raise ParameterError(name, f"must be finite, was {value!r}")
    if positive and v <= 0:
        raise ParameterError(name, f"must be > 0, was {value!r}")
    if non_negative and v < 0:
        raise ParameterError(name, f"must be >= 0, was {value!r}")
    if non_zero and v == 0:
        raise ParameterError(name, "must not be 0")
    return v


def validate(
    op: ArrayLike, pv: ArrayLike, *, ts: Any, kp: Any, delay: Any, process: Any,
    op_range: Any, k: Any,
) -> tuple[FloatArray, FloatArray, float, float | None, float, float | None, float]:
    op_a = _series("op", op)
    pv_a = _series("pv", pv)
    if op_a.size != pv_a.size:
        raise ParameterError("pv", f"must have the same length as op ({pv_a.size} != "
                                   f"{op_a.size})")
    ts_ = _scalar("ts", ts, positive=True)
    kp_ = None if kp is None else _scalar("kp", kp, non_zero=True)
    delay_ = _scalar("delay", delay, non_negative=True)
    if process not in PROCESSES:
        raise ParameterError("process", f"must be one of {', '.join(PROCESSES)}; was "
                                        f"{process!r}")
    span: float | None = None
    if op_range is not None:
        try:
            lo, hi = op_range
        except (TypeError, ValueError) as exc:
            raise ParameterError("op_range", f"must be a pair (lo, hi), was {op_range!r}"
                                 ) from exc
        lo_ = _scalar("op_range", lo)
        hi_ = _scalar("op_range", hi)
        if hi_ <= lo_:
            raise ParameterError("op_range", f"must have lo < hi, was {op_range!r}")
        span = hi_ - lo_
    k_ = _scalar("k", k)
    if not 1.0 <= k_ <= 2.0:
        raise ParameterError("k", f"must lie in [1, 2], was {k!r}")
    return op_a, pv_a, ts_, kp_, delay_, span, k_


def along(name: str, value: ArrayLike | None, n: int) -> FloatArray | None:
    """An optional series sampled with OP (``n`` samples), validated."""
    arr = None if value is None else _series(name, value)
    if arr is not None and arr.size != n:
        raise ParameterError(name, f"must have the same length as op ({arr.size} != {n})")
    return arr
