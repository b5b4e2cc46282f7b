"""Stiction detection by curve fitting (He, Wang, Pottmann & Qin 2007).

A sticky valve in a loop with integral action turns the controller output of a
self-regulating loop (and the PV of an integrating loop) into a triangle wave, while
tuning problems and external disturbances give a sinusoid. The oscillating signal is split
into half periods at its zero crossings (mean and linear trend removed); each half period is
fitted with a half sine and with a triangle, and

    SI = MSE_sine / (MSE_sine + MSE_triangle),

SI >= 0.6 stiction, SI <= 0.4 no stiction, in between undetermined.

Our readings: the half sine is zero at both crossings (amplitude and offset free); the
triangle has its apex at the half period's extremum of the lightly smoothed signal (again
amplitude and offset free), so both shapes have the same two linear parameters. Zero
crossings are taken on a moving average of a twelfth of the period with hysteresis of 10 %
of the amplitude, so noise does not split half periods. The measurement-noise variance
(estimated from second differences) is removed from both mean squared errors before the
ratio: noise adds equally to both and would otherwise pull SI towards 0.5.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
from scipy import ndimage

from ._oscillation import detrend
from ._validate import FloatArray

__all__ = ["NO_STICTION_SI", "STICTION_SI", "StictionIndex", "half_periods", "stiction_index"]

STICTION_SI = 0.6
NO_STICTION_SI = 0.4


@dataclasses.dataclass(frozen=True)
class StictionIndex:
    si: float | None
    half_periods: int
    mse_sine: float
    mse_triangle: float


def noise_sd(x: FloatArray) -> float:
    """Robust white-noise SD from second differences (insensitive to slow signal)."""
    if x.size < 4:
        return 0.0
    d2 = np.diff(x, 2)
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return 1.4826 * mad / math.sqrt(6.0)


def half_periods(x: FloatArray, period: float) -> tuple[FloatArray, FloatArray]:
    """Zero crossings of detrended ``x`` (fractional sample positions) and the smoothed
    signal they were found on. Crossings closer than a sixth of the period are merged."""
    y = detrend(x)
    win = max(1, round(period / 12.0))
    ys = ndimage.uniform_filter1d(y, win, mode="nearest") if win > 1 else y
    amp = 0.5 * float(np.percentile(ys, 95) - np.percentile(ys, 5))
    h = 0.1 * amp
    state = np.where(ys > h, 1, np.where(ys < -h, -1, 0))
    nz = np.flatnonzero(state)
    if nz.size < 2:
        return np.empty(0), ys
    st = state[nz]
    change = np.flatnonzero(st[1:] != st[:-1]) + 1  # positions in nz where state flips
    # the crossing: last sign change of ys before the sample where the new state begins
    raw = np.flatnonzero(np.signbit(ys[1:]) != np.signbit(ys[:-1]))  # between raw, raw+1
    ends = nz[change]
    k = np.searchsorted(raw, ends, side="left") - 1
    k = np.clip(k, 0, max(raw.size - 1, 0))
    if raw.size == 0:
        return np.empty(0), ys
    i = raw[k]
    a, b = ys[i], ys[i + 1]
    z = i + np.where(a != b, a / (a - b), 0.5)
    z = np.unique(z)
    if z.size > 1:
        keep = np.concatenate(([True], np.diff(z) > period / 6.0))
        z = z[keep]
    return np.asarray(z, dtype=np.float64), ys


def stiction_index(x: FloatArray, period: float) -> StictionIndex:
    """He et al. (2007) stiction index of ``x`` oscillating with ``period`` samples."""
    z, ys = half_periods(x, period)
    y = detrend(x)
    var_noise = noise_sd(x) ** 2
    sse_s = sse_t = 0.0
    count = n_used = 0
    for z0, z1 in itertools.pairwise(z):
        length = z1 - z0
        if not 0.25 * period < length < 1.5 * period:
            continue  # not a half period of the main oscillation
        i0, i1 = int(np.floor(z0)) + 1, int(np.ceil(z1))
        if i1 - i0 < 4:
            continue
        seg = y[i0:i1]
        u = (np.arange(i0, i1) - z0) / length
        sine = np.sin(np.pi * u)
        k = int(np.argmax(np.sign(seg.mean()) * ys[i0:i1]))  # the half period's extremum
        up = float(np.clip(u[k], 0.05, 0.95))
        tri = np.where(u <= up, u / up, (1.0 - u) / (1.0 - up))
        sse_s += _sse(seg, sine)
        sse_t += _sse(seg, tri)
        n_used += seg.size
        count += 1
    if count < 2:
        return StictionIndex(None, count, 0.0, 0.0)
    mse_s = max(sse_s / n_used - var_noise, 0.0)
    mse_t = max(sse_t / n_used - var_noise, 0.0)
    total = mse_s + mse_t
    si = 0.5 if total <= 1e-12 * max(float(np.var(y)), 1e-300) else mse_s / total
    return StictionIndex(si, count, mse_s, mse_t)


def _sse(y: FloatArray, basis: FloatArray) -> float:
    """Residual sum of squares of y ~ c + a * basis (least squares)."""
    bc = basis - basis.mean()
    yc = y - y.mean()
    den = float(bc @ bc)
    a = float(bc @ yc) / den if den > 0 else 0.0
    r = yc - a * bc
    return float(r @ r)
