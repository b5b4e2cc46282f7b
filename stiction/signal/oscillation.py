"""Oscillation detection and period estimate from the autocorrelation function.

Thornhill, Huang & Zhang (2003), "Detection of multiple oscillations in control loops",
J. Process Control 13, 91-100: the zero crossings of the ACF of an oscillating signal are
evenly spaced, and the oscillation is regular when the mean period (twice the mean crossing
interval) exceeds three standard deviations of the individual periods:
``r = mean(Tp) / (3 std(Tp)) > 1``. The ACF filters out noise, so this works on raw data.

Significance. The ACF of white noise also crosses zero, at random, and now and then evenly
enough to pass the regularity test (a settled healthy loop: OP is noise, and 30 % of its
half-hour windows used to come out "oscillating" with a period of 3-5 samples). So the
oscillation must also be significant: the ACF lobe one period out (between the second and
third crossings) must reach ``SIGNIFICANCE / sqrt(n)``; for white noise the ACF at a lag has
standard deviation about ``1 / sqrt(n)``. Measured lobe heights x sqrt(n): settled healthy
loops 0-2.5, the paper's limit cycles 10-100, the plant records' sticky flow loop 4-11.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from scipy import fft

from .._validate import FloatArray
from .arrays import centred_time, dot, median, medians

__all__ = ["Oscillation", "acf", "baseline", "detect_oscillation", "detect_oscillations"]

MAX_CROSSINGS = 11  # Thornhill uses the first ten intervals
MIN_CROSSINGS = 4  # at least two period estimates
MIN_PERIOD = 8.0  # samples: faster oscillations cannot be told triangle from sine
SIGNIFICANCE = 3.0  # the ACF lobe at one period must reach this / sqrt(n)


@dataclasses.dataclass(frozen=True)
class Oscillation:
    """``period`` in samples (None when no regular oscillation was seen)."""

    oscillating: bool
    period: float | None
    regularity: float
    reason: str
    significance: float = 0.0  # the ACF lobe one period out, times sqrt(n)


def detrend(x: FloatArray) -> FloatArray:
    """``x`` minus its least-squares straight line."""
    t, tt = centred_time(x.size)
    mean = np.add.reduce(x) / x.size  # x.mean(), without its Python layer
    slope = dot(t, x - mean) / tt
    return np.asarray(x - mean - slope * t)


def baseline(x: FloatArray, window: int) -> FloatArray:
    """A running median of ``x`` over about ``window`` samples, cheaply: medians of blocks of
    ``window // 16`` samples, a running median of 17 of those, interpolated back.

    Subtracted from a signal it removes set-point and load steps and slow drift but keeps
    any oscillation of period well under ``window``: a median over a window spanning more
    than a cycle sits in the middle of the cycle, and a median filter keeps a step's edge
    where a moving average would smear it into a ramp (which the shape tests would read as
    a triangle)."""
    n = x.size
    b = max(1, window // 16)
    m = n // b
    if m < 3:
        return np.full(n, median(x))
    blocks = medians(x[: m * b].reshape(m, b))
    k = min(17, m if m % 2 else m - 1)
    h = k // 2
    padded = np.concatenate((np.full(h, blocks[0]), blocks, np.full(h, blocks[-1])))
    med = medians(np.lib.stride_tricks.sliding_window_view(padded, k))
    centres = np.arange(m) * b + (b - 1) / 2.0
    return np.asarray(np.interp(np.arange(n), centres, med))


def acf(x: FloatArray) -> FloatArray:
    """Biased autocorrelation of ``x`` (mean removed) for lags 0..n-1, acf[0] = 1; of each
    row for a 2-D ``x`` (one FFT for all rows: pocketfft does two rows in little more than
    the time of one, with the same result)."""
    n = x.shape[-1]
    y = x - np.add.reduce(x, axis=-1, keepdims=True) / n
    nfft = fft.next_fast_len(2 * n, real=True)
    f = fft.rfft(y, nfft, axis=-1)
    r = fft.irfft(f.real**2 + f.imag**2, nfft, axis=-1)[..., :n]
    r0 = r[..., :1]
    return np.asarray(np.where(r0 > 0, r / np.where(r0 > 0, r0, 1.0), 0.0))


def detect_oscillation(x: FloatArray, *, min_regularity: float = 1.0) -> Oscillation:
    """Is ``x`` (1-D, finite) regularly oscillating, and with what period (samples)?"""
    return _from_acf(acf(detrend(x)), min_regularity)


def detect_oscillations(xs: Sequence[FloatArray], *, min_regularity: float = 1.0
                        ) -> list[Oscillation]:
    """:func:`detect_oscillation` of each of several signals of one length, their ACFs two
    at a time (larger batches gain nothing more, and their temporaries outgrow the
    allocator's heap: fresh pages from the OS at every call)."""
    out: list[Oscillation] = []
    for i in range(0, len(xs), 2):
        r = acf(np.array([detrend(x) for x in xs[i : i + 2]]))
        out.extend(_from_acf(row, min_regularity) for row in r)
    return out


def _from_acf(r: FloatArray, min_regularity: float) -> Oscillation:
    """The oscillation seen in the ACF ``r`` of a signal of ``r.size`` samples."""
    n = r.size
    max_lag = (2 * n) // 3
    seg = r[1:max_lag]
    sgn = np.signbit(seg)
    idx = (sgn[1:] != sgn[:-1]).nonzero()[0][:MAX_CROSSINGS]
    if idx.size < MIN_CROSSINGS:
        return Oscillation(False, None, 0.0,
                           f"no regular oscillation: the ACF crosses zero only {idx.size} times "
                           f"within 2/3 of the window")
    # linear interpolation of each crossing; lag of seg[i] is i + 1
    a, b = seg[idx], seg[idx + 1]
    z = idx + 1 + a / (a - b)
    periods = z[2:] - z[:-2]
    tp = float(np.add.reduce(periods) / periods.size)
    dev = periods - tp
    sd = math.sqrt(float(np.add.reduce(dev * dev) / dev.size))  # periods.std()
    reg = float("inf") if sd == 0 else tp / (3.0 * sd)
    if reg <= min_regularity:
        return Oscillation(False, tp, reg,
                           f"no regular oscillation: ACF zero crossings irregular "
                           f"(regularity {reg:.2f} <= {min_regularity:g})")
    lobe = seg[int(np.ceil(z[1])) - 1 : int(np.floor(z[2]))]
    height = float(np.maximum.reduce(np.abs(lobe))) * math.sqrt(n) if lobe.size else 0.0
    if height < SIGNIFICANCE:
        return Oscillation(False, None, reg,
                           f"no significant oscillation: the ACF one period out is "
                           f"{height:.1f}/sqrt(n), under the {SIGNIFICANCE:g}/sqrt(n) that "
                           "noise alone can reach", height)
    return Oscillation(True, tp, reg, f"regular oscillation (regularity {min(reg, 99.0):.1f})",
                       height)
