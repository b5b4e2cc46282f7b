"""The white-noise level of a signal, robust to the slow signal under it."""

from __future__ import annotations

import math

import numpy as np

from .._validate import FloatArray
from .arrays import median


def noise_sd(x: FloatArray) -> float:
    """Robust white-noise SD from second differences (insensitive to slow signal)."""
    if x.size < 4:
        return 0.0
    d1 = x[1:] - x[:-1]
    d2 = d1[1:] - d1[:-1]  # np.diff(x, 2), without its Python layer
    mad = median(np.abs(d2 - median(d2)))
    return 1.4826 * mad / math.sqrt(6.0)
