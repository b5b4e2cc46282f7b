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

That correction makes SI the ratio of two differences, and when the two shapes' misfits
differ by less than noise can make them differ, SI swings to 0 or 1 by chance: an
aggressively tuned loop with PV noise 0.2 gave SI 0.97. So ``resolved`` asks whether the
paired difference ``D = (SSE_sine - SSE_triangle)`` over the ``n`` samples used stands out
of the noise: the noise enters ``D`` mainly through its projection on the difference of the
two fitted shapes, with variance about ``4 var_noise |D|``, so ``z = sqrt(|D| / var_noise) / 2``
must reach ``SHAPE_Z``. That variance is a rough model, so the threshold is set from
measurements, with a wide margin on both sides: z of the paper's sticky loops with PV noise
SD up to 0.5 is 34-430, of the plant's sticky flow loop 83-260; of noise-dominated signals
(unit sine or triangle under noise SD 1-3, an aggressively tuned loop rung by PV noise alone)
1.8-5.2, and the one of those that came out SI 0.97 had z 1.8. The caller must not decide on
an unresolved SI.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import ndimage

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.arrays import dot, percentiles
from ..signal.cycle import MIN_CYCLES, Signal
from ..signal.noise import noise_sd
from ..signal.oscillation import MIN_PERIOD, detrend
from ..signal.segments import ragged, row_chunks
from .base import Window

__all__ = ["NO_STICTION_SI", "SHAPE_CYCLES", "STICTION_SI", "StictionIndex", "detect_op",
           "detect_pv", "half_periods", "stiction_index"]

STICTION_SI = 0.6
NO_STICTION_SI = 0.4
SHAPE_Z = 8.0  # the sine/triangle misfit difference must stand this far out of the noise


@dataclasses.dataclass(frozen=True)
class StictionIndex:
    si: float | None
    half_periods: int
    mse_sine: float
    mse_triangle: float
    resolved: bool = True  # the shape misfits stand out of the noise (see module doc)


def half_periods(x: FloatArray, period: float, *,
                 detrended: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """Zero crossings of detrended ``x`` (fractional sample positions) and the smoothed
    signal they were found on. Crossings closer than a sixth of the period are merged.
    ``detrended``: ``detrend(x)``, when the caller has it already."""
    y = detrend(x) if detrended is None else detrended
    win = max(1, round(period / 12.0))
    ys = ndimage.uniform_filter1d(y, win, mode="nearest") if win > 1 else y
    p5, p95 = percentiles(ys, (5.0, 95.0))
    amp = 0.5 * float(p95 - p5)
    h = 0.1 * amp
    state = np.where(ys > h, 1, np.where(ys < -h, -1, 0))
    nz = state.nonzero()[0]
    if nz.size < 2:
        return np.empty(0), ys
    st = state[nz]
    change = (st[1:] != st[:-1]).nonzero()[0] + 1  # positions in nz where state flips
    # the crossing: last sign change of ys before the sample where the new state begins
    sb = np.signbit(ys)
    raw = (sb[1:] != sb[:-1]).nonzero()[0]  # between raw, raw+1
    ends = nz[change]
    k = raw.searchsorted(ends, side="left") - 1
    k = np.minimum(np.maximum(k, 0), max(raw.size - 1, 0))
    if raw.size == 0:
        return np.empty(0), ys
    i = raw[k]
    a, b = ys[i], ys[i + 1]
    z = i + np.where(a != b, a / (a - b), 0.5)
    # z is nondecreasing (one crossing per flip, in order): its distinct values, as np.unique
    z = z[np.concatenate(([True], z[1:] != z[:-1]))]
    if z.size > 1:
        keep = np.concatenate(([True], z[1:] - z[:-1] > period / 6.0))
        z = z[keep]
    return np.asarray(z, dtype=np.float64), ys


def stiction_index(x: FloatArray, period: float, *, detrended: bool = False,
                   noise: float | None = None) -> StictionIndex:
    """He et al. (2007) stiction index of ``x`` oscillating with ``period`` samples.

    ``detrended``: ``x`` has its mean and straight line removed already (as the cycle's
    signals have); ``noise``: the white-noise SD of the signal ``x`` was made from (by
    second differences, :func:`~stiction.signal.noise.noise_sd`, which a straight line does
    not change and the few knots of a running-median baseline barely move), when the caller
    has it.

    Many half periods are fitted at once: each is one row of a zero-padded matrix (rows of
    similar length together, a few thousand entries at a time), and both two-parameter fits
    (offset + amplitude of the sine, of the triangle) follow in closed form from the row
    sums."""
    y = x if detrended else detrend(x)
    z, ys = half_periods(x, period, detrended=y)
    var_noise = (noise_sd(x) if noise is None else noise) ** 2
    z0, z1 = z[:-1], z[1:]
    length = z1 - z0
    i0 = np.floor(z0).astype(np.intp) + 1
    i1 = np.ceil(z1).astype(np.intp)
    # only half periods of the main oscillation, with enough samples to have a shape
    keep = (0.25 * period < length) & (length < 1.5 * period) & (i1 - i0 >= 4)
    count = int(np.count_nonzero(keep))
    if count < 2:
        return StictionIndex(None, count, 0.0, 0.0)
    z0, length, i0, n_k = z0[keep], length[keep], i0[keep], (i1 - i0)[keep]
    order = n_k.argsort(kind="stable")
    sse_s = sse_t = 0.0
    for sl in row_chunks(n_k[order]):
        rows = order[sl]
        s, t = _sse_pair(y, ys, (z0[rows], length[rows]), i0[rows], n_k[rows])
        sse_s += s
        sse_t += t
    n_used = float(np.add.reduce(n_k))
    # each fit spends two parameters per half period on the noise: the residual keeps
    # (n - 2 count) / n of its variance
    noise_part = var_noise * max(1.0 - 2.0 * count / n_used, 0.0)
    mse_s = max(sse_s / n_used - noise_part, 0.0)
    mse_t = max(sse_t / n_used - noise_part, 0.0)
    total = mse_s + mse_t
    # var(y) <= mean(y^2): a cheap bound decides the common case without the variance
    if total > 1e-12 * max(dot(y, y) / y.size, 1e-300) or \
            total > 1e-12 * max(float(np.var(y)), 1e-300):
        si = mse_s / total
    else:
        si = 0.5
    diff = abs(sse_s - sse_t)
    resolved = var_noise == 0.0 or math.sqrt(diff / var_noise) / 2.0 >= SHAPE_Z
    return StictionIndex(si, count, mse_s, mse_t, resolved=resolved)


def _sse_pair(y: FloatArray, ys: FloatArray, span: tuple[FloatArray, FloatArray],
              i0: np.ndarray, n: np.ndarray) -> tuple[float, float]:
    """Residual sums of squares of the half-sine and the triangle fits over the half periods
    ``y[i0[k]:i0[k] + n[k]]`` (zero crossings ``z0``, ``z0 + length``)."""
    z0, length = span
    idx, mask = ragged(i0, n)
    nf = n.astype(np.float64)
    seg = np.where(mask, y[idx], 0.0)
    row_sum = np.add.reduce(seg, axis=1)
    yc = np.where(mask, seg - (row_sum / nf)[:, None], 0.0)
    u = (idx - z0[:, None]) / length[:, None]
    sine = np.sin(np.pi * u)
    # the triangle's apex: the half period's extremum of the smoothed signal
    sgn = np.sign(row_sum)
    k = np.where(mask, sgn[:, None] * ys[idx], -np.inf).argmax(axis=1)[:, None]
    up = np.minimum(np.maximum(u[np.arange(u.shape[0])[:, None], k], 0.05), 0.95)
    tri = np.where(u <= up, u / up, (1.0 - u) / (1.0 - up))
    sse = _sse_rows(yc, np.array((sine, tri)), mask, nf)
    return float(np.add.reduce(sse[0])), float(np.add.reduce(sse[1]))


def _sse_rows(yc: FloatArray, basis: FloatArray, mask: np.ndarray, n: FloatArray) -> FloatArray:
    """Per row, the residual sum of squares of y ~ c + a * basis over the masked entries,
    from the centred rows ``yc`` of y (centred first, so the closed form does not cancel);
    ``basis`` stacks several bases (axis 0), each fitted on its own."""
    b = np.where(mask, basis, 0.0)
    bc = np.where(mask, b - (np.add.reduce(b, axis=2) / n)[..., None], 0.0)
    den = np.einsum("kij,kij->ki", bc, bc)
    num = np.einsum("kij,ij->ki", bc, yc)
    a = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    r = yc - a[..., None] * bc
    return np.asarray(np.einsum("kij,kij->ki", r, r))


# ----------------------------------------------------------------------------- the detectors
SHAPE_CYCLES = 5.0
"""Periods the stiction index needs before it votes: an SI over fewer than ten half cycles
swings by +-0.1 from window to window on one loop (a sine-like disturbance reads 0.62 on four
cycles of a Tennessee Eastman run), across the 0.6 line."""


def _si(name: str, s: Signal, fallback: float | None, noise: float) -> Evidence:
    label = name[-2:].upper()
    period = s.osc.period if s.osc.oscillating else fallback
    if period is None:
        return Evidence(name, None, 0, f"{label} does not cycle")
    if period < MIN_PERIOD:
        return Evidence(name, None, 0, f"{label} cycles too fast to see its shape "
                        f"({period:.1f} samples a period, need {MIN_PERIOD:g})")
    if s.x.size / period < MIN_CYCLES:
        return Evidence(name, None, 0, f"{label}: {s.x.size / period:.1f} cycles, too few "
                        f"to judge the shape (need {SHAPE_CYCLES:g})")
    si = stiction_index(s.x, period, detrended=True, noise=noise)
    if si.si is None:
        return Evidence(name, None, 0, f"too few clean half periods in {label} to fit")
    if not si.resolved:
        return Evidence(name, si.si, 0, f"{label} too noisy to tell a triangle from a sine")
    cycles = s.x.size / period
    if cycles < SHAPE_CYCLES:
        return Evidence(name, si.si, 0, f"{label}: SI {si.si:.2f} over {cycles:.1f} cycles, "
                        f"too few to vote (need {SHAPE_CYCLES:g})")
    if si.si >= STICTION_SI:
        return Evidence(name, si.si, 1, f"{label} half cycles fit a triangle")
    if si.si <= NO_STICTION_SI:
        return Evidence(name, si.si, -1, f"{label} half cycles fit a sine")
    return Evidence(name, si.si, 0, f"{label} neither triangular nor sinusoidal")


def detect_op(w: Window) -> Evidence:
    """``si_op``: OP's half cycles, a triangle (+1, SI >= 0.6) or a sine (-1, SI <= 0.4),
    only when the shapes stand out of the noise and the window holds ``SHAPE_CYCLES``. A
    sticky valve makes OP a triangle in a fast self-regulating loop."""
    return _si("si_op", w.cycle.op, w.cycle.period, w.noise[0])


def detect_pv(w: Window) -> Evidence:
    """``si_pv``: the same on PV, where a sticky valve draws its triangle in an integrating
    or slow loop. Both run whatever the process type, so a level loop analysed as
    self-regulating still shows its triangle."""
    return _si("si_pv", w.cycle.pv, w.cycle.period, w.noise[1])
