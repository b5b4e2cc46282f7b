"""Which of two signals that share a cycle drives the other: Granger causality on the
band-passed cycle, and the phase lag of the fundamental.

A cycle born in one loop reaches the others later, and what varies from one cycle to the
next at the source (its period and amplitude wander) shows up downstream after it. So the
past of the source's cycle helps predict a follower's beyond the follower's own past, and
not the other way round: Granger causality (Granger 1969; used to find the root cause of
plant-wide oscillations by Yuan and Qin 2014, J. Process Control 24(2), 1-14; transfer
entropy, its nonlinear sibling, by Bauer et al. 2007, IEEE Trans. Control Syst. Technol.
15(1), 12-21).

:func:`cycle_band`: both signals band-passed around the cycle (as for the nonlinearity
index, :mod:`.nonlinearity`) and resampled to ``SAMPLES_PER_CYCLE`` a cycle on one time
grid. :func:`granger`: ``ORDER`` past samples (half a cycle) of the driven signal, with and
without as many of the driver's; the gain is ``ln(RSS without / RSS with)`` less what chance
gives at the ``SIGNIFICANCE`` level of the F test with that many samples (0 when not
significant: a few cycles of two independent loops at one period gave 0.15 by chance);
the net flow from ``a`` to ``b`` is the gain a -> b less the gain b -> a (positive: ``a``
leads).

:func:`phase_lag`: the phase of the fundamental of ``b`` against ``a`` (the cross-spectrum
in the cycle's band) as a time in seconds, folded into a quarter period either way (the
sign of a path's gain is not known, so half a period apart is the same cycle inverted).
Positive: ``b`` lags ``a``. Reported, not used for the ranking: a closed loop turns the
phase of what it rejects by up to a quarter period either way.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import signal as sp_signal

from .._validate import FloatArray

__all__ = ["ORDER", "band_passed", "cycle_band", "cycle_bands", "granger", "net_flow",
           "phase_lag"]

SAMPLES_PER_CYCLE = 16
ORDER = 8  # half a cycle of the past
SIGNIFICANCE = 0.01
MAX_CYCLES = 64
LOW, HIGH = 0.5, 5.5


def cycle_band(x: FloatArray, period: float) -> FloatArray:
    """``x`` (gaps filled) band-passed around its cycle of ``period`` samples and resampled
    to ``SAMPLES_PER_CYCLE`` a cycle: its last ``MAX_CYCLES`` cycles, unit variance. Two
    signals of one length give two series on one grid."""
    return np.asarray(cycle_bands(np.asarray(x, dtype=np.float64)[None, :], period)[0])


def cycle_bands(xs: FloatArray, period: float) -> FloatArray:
    """:func:`cycle_band` of each row of ``xs`` (one filter run over all rows)."""
    n = xs.shape[1]
    y = band_passed(np.asarray(xs, dtype=np.float64), period)
    start = max(0.0, n - 1 - MAX_CYCLES * period)
    grid = np.arange(n - 1.0, start, -period / SAMPLES_PER_CYCLE)[::-1]
    lo = np.minimum(np.floor(grid).astype(np.intp), n - 2)
    w = grid - lo
    z = y[:, lo] * (1.0 - w) + y[:, lo + 1] * w
    sd = z.std(axis=1, keepdims=True)
    return np.asarray(np.divide(z, sd, out=np.zeros_like(z), where=sd > 0))


def band_passed(x: FloatArray, period: float) -> FloatArray:
    """``x`` (or each row of it) less its mean, band-passed from ``LOW`` to ``HIGH`` times
    its cycle's frequency (capped below Nyquist): a zero-phase second-order Butterworth
    filter."""
    f0 = 1.0 / period
    high = min(HIGH * f0, 0.45)
    y = x - np.mean(x, axis=-1, keepdims=True)
    if LOW * f0 >= high:
        return np.asarray(y)
    return np.asarray(sp_signal.sosfiltfilt(_bandpass(round(2.0 * LOW * f0, 9),
                                                      round(2.0 * high, 9)), y, axis=-1))


@functools.lru_cache(maxsize=64)
def _bandpass(low: float, high: float) -> FloatArray:
    """The filter's second-order sections (one design per group: its members share it)."""
    return np.asarray(sp_signal.butter(2, [low, high], btype="bandpass", output="sos"))


def _lagged(x: FloatArray) -> FloatArray:
    """Rows t = ORDER..n-1, columns x[t-1], ..., x[t-ORDER]."""
    n = x.size
    return np.column_stack([x[ORDER - k:n - k] for k in range(1, ORDER + 1)])


def granger(a: FloatArray, b: FloatArray) -> float:
    """``ln(RSS(b | b's past) / RSS(b | b's and a's past))``: how much ``a``'s past helps
    predict ``b`` (0: not at all). ``a`` and ``b`` from :func:`cycle_band`, one grid."""
    if a.size != b.size or a.size <= 4 * ORDER:
        return 0.0
    target = b[ORDER:]
    own = np.column_stack((_lagged(b), np.ones(target.size)))
    both = np.column_stack((own, _lagged(a)))
    rss = []
    for design in (own, both):
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        r = target - design @ coef
        rss.append(float(r @ r))
    if not (rss[1] > 0 and rss[0] > 0):
        return 0.0
    dof = target.size - both.shape[1]
    chance = math.log1p(ORDER * _f_critical(ORDER, dof) / dof) if dof > 0 else math.inf
    return max(0.0, math.log(rss[0] / rss[1]) - chance)


@functools.cache
def _f_critical(p: int, dof: int) -> float:
    """The F distribution's upper ``SIGNIFICANCE`` point with (p, dof) degrees of freedom."""
    from scipy.stats import f  # noqa: PLC0415  (scipy.stats loads slowly; once, on use)

    return float(f.isf(SIGNIFICANCE, p, dof))


def net_flow(a: FloatArray, b: FloatArray) -> float:
    """Granger gain a -> b less b -> a: positive when ``a`` leads ``b``."""
    return granger(a, b) - granger(b, a)


def phase_lag(a: FloatArray, b: FloatArray, period: float, ts: float) -> float:
    """Seconds by which ``b``'s fundamental lags ``a``'s (negative: leads), within a quarter
    period either way; both of one length, ``period`` in samples."""
    n = min(a.size, b.size)
    fa, fb = np.fft.rfft(a[-n:] - np.mean(a[-n:])), np.fft.rfft(b[-n:] - np.mean(b[-n:]))
    freqs = np.fft.rfftfreq(n)
    f0 = 1.0 / period
    band = (freqs >= 0.88 * f0) & (freqs <= 1.12 * f0)
    if not band.any():
        return 0.0
    cross = complex(np.sum(fa[band] * np.conj(fb[band])))
    phi = math.atan2(cross.imag, cross.real)  # b lags a by phi (radians)
    if phi > math.pi / 2:
        phi -= math.pi
    elif phi <= -math.pi / 2:
        phi += math.pi
    return phi / (2.0 * math.pi) * period * ts
