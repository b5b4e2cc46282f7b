"""Horch's stiction tests: OP-PV cross-correlation, and PV curvature for integrating loops.

References
----------
A. Horch (1999), "A simple method for detection of stiction in control valves", Control
Engineering Practice 7(10), 1221-1231 (self-regulating loops).
A. Horch (2000), "Condition Monitoring of Control Loops", PhD thesis, Royal Institute of
Technology (KTH), Stockholm; A. Horch and A. J. Isaksson (2001), "Detection of valve stiction
in integrating processes", European Control Conference, Porto (integrating loops; issue 13
also cites Horch 2002, "Patterns for stiction in integrating processes", not checked here).
We had neither paper's text at hand: the rules below follow the published idea, and every
number in them is ours and says so.

Self-regulating loops: the cross-correlation of OP and PV
----------------------------------------------------------
A sticky valve in a self-regulating loop with integral action makes OP a ramp (a triangle)
while PV sits still and then jumps (a square wave): PV changes while OP is at its turning
points, a quarter period away from OP's zero crossings. The cross-correlation function (CCF)
of OP and PV is then odd about lag 0 (zero at lag 0, extremes either side). A linear cycle
(tuning, or a disturbance the loop fights) has OP and PV in or against phase: the CCF is
even (extreme at lag 0). Horch's rule: odd -> stiction, even -> no stiction.

Algorithm as implemented:

1. OP and PV are each scaled by their largest magnitude, mean and straight line removed (no
   units or offsets survive).
2. Period ``P``: the caller's, or the ACF period of PV (Thornhill et al. 2003, as
   :func:`stiction.signal.oscillation.detect_oscillation`), else of OP; neither oscillating: vote 0.
   Fewer than ``MIN_SAMPLES`` (32) samples, a period under ``MIN_PERIOD`` (4 samples: the
   ACF reports such periods on noise) or fewer than ``MIN_CYCLES`` (3) periods: vote 0.
3. CCF ``r(tau) = corr(OP(t), PV(t + tau))`` (biased, normalised, by FFT).
4. The zero crossings nearest lag 0 on each side, ``tau_r >= 0`` and ``tau_l >= 0`` (the
   left one as a distance), by linear interpolation, searched out to ``0.75 P``. For
   ``r(tau) ~ cos(2 pi tau / P + phi)`` they are ``P/4 -+ phi P / (2 pi)`` apart from lag 0,
   so Horch's phase of the CCF is
   ``phase = 90 deg * |tau_r - tau_l| / (tau_r + tau_l)``: 0 deg even, 90 deg odd.
   The lobe checks: ``tau_r + tau_l`` must be between ``LOBE_MIN`` and ``LOBE_MAX`` (1/4 and
   3/4) of ``P`` (it is P/2 for any periodic pair; noise gives crossings a few lags apart),
   and the largest ``|r|`` within half a period of lag 0 must reach
   ``SIGNIFICANCE / sqrt(n)`` (3, as the oscillation detector's ACF test); else vote 0.
5. Vote (the thresholds are ours; Horch states odd vs even without numbers): phase >=
   ``ODD_PHASE`` (60 deg) +1, phase <= ``EVEN_PHASE`` (30 deg) -1, in between 0. Also
   reported: ``r0_ratio = |r(0)| / max |r|`` within half a period (1 even, 0 odd), which is
   ``|cos phi|`` for sinusoids.

Sees well: fast self-regulating loops (flow, pressure), where PV follows the valve within a
small part of the period. Fails: large dead time or slow processes (PV lags OP by more, the
CCF shifts and looks less odd), integrating processes (OP and PV are a quarter period apart
whatever the valve does: use ``integrating=True``) and loops that act as integrators at the
cycle's frequency (a temperature driven by coolant flow: the Tennessee Eastman reactor-
temperature loops read odd, 84-87 deg, with no sticky valve), external sinusoidal
disturbances (the phase is anywhere between even and odd; 38 deg on the ``disturbance``
scenario, vote 0).

Integrating loops: the distribution of PV's curvature
------------------------------------------------------
In an integrating loop (level), a sticky valve holds a constant flow between jumps, so PV is
made of ramps with sharp turns: its second derivative is zero except at the jumps. A linear
cycle makes PV a sine, whose second derivative is a sine too. Horch compares the
distribution of the (filtered) second difference of PV with a Gaussian and with a two-peaked
distribution (a sine plus Gaussian noise): a sine's values pile up near its extremes
(arcsine density, two peaks), the spikes of a sticky valve give a peak at zero with long
tails. So for the second difference two-peaked means sinusoidal, not sticky; a summary
reading "bimodal = sticky" has it backwards (it would fit the first difference, a square wave
under stiction, but a sine's first difference is two-peaked as well).

Algorithm as implemented:

1. PV scaled and detrended as above; period as above (from PV).
2. Curvature at the scale of the cycle: a moving average of ``h = P / CURVE_FRACTION``
   samples (12 per period, at least 1), then ``d(t) = s(t + h) - 2 s(t) + s(t - h)``; ``h``
   samples cut at both ends.
3. Noise: the white-noise SD of PV from its second differences (robust MAD, as
   :func:`stiction.signal.noise.noise_sd`), and at least the rounding noise ``q / sqrt(12)`` of
   PV's quantum ``q`` (its smallest non-zero step: on a quantised level reading most second
   differences are 0 and the MAD says "no noise"), predicts the SD of ``d`` from noise alone,
   ``sigma sqrt(6 / h)``; ``curvature_snr = SD(d) / that``. Below ``MIN_SNR`` (3, noise at most
   a ninth of the variance of ``d``): vote 0, the curvature is mostly noise.
4. Fits. Gaussian: kurtosis 3. Two-peaked model A sin + N(0, s^2), fitted by its variance
   and kurtosis: its kurtosis is ``3 - 1.5 q^2`` with ``q = (A^2/2) / var`` the sine's share
   of the variance, so ``sine_share = sqrt((3 - kurtosis) / 1.5)`` (0 when the kurtosis is 3
   or more: the two-peaked model then collapses onto the Gaussian and fits no better).
5. Vote (thresholds ours): kurtosis >= ``SPIKY_KURTOSIS`` (4: heavier tails than a Gaussian,
   the spikes of ramps with sharp turns; a clean triangle wave gives 4.5 at h = P/12, the
   Table 5 sticky level loops 4.9-6.7) +1;
   kurtosis <= ``SINE_KURTOSIS`` (2.25: the fitted sine carries at least 71 % of the variance)
   -1; in between 0. A Gaussian curvature (kurtosis near 3) is not counted as stiction: a
   loop rung by random load is a narrow-band Gaussian process whose curvature is Gaussian
   too (measured 2.8-3.2 on an aggressively tuned level loop).

Sees well: level loops with a clean stick-slip cycle (kurtosis 4.9-6.7 on the Table 5
loops).
Fails: noisy PV with slow cycles (snr gate), set-point steps or load steps inside the
window (a step is a curvature spike and reads sticky), non-sinusoidal linear cycles.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import fft, ndimage

from .. import _validate as v
from .._assessment import Evidence
from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.arrays import dot, unit_detrended
from ..signal.noise import noise_sd
from ..signal.oscillation import detect_oscillation
from .base import Window

__all__ = ["Horch", "detect", "horch_test"]

MIN_SAMPLES = 32  # shorter records: too short to tell
MIN_PERIOD = 4.0  # samples: a faster cycle cannot show a lobe or a curvature
MIN_CYCLES = 3.0  # periods the record must hold
SEARCH = 0.75  # zero crossings of the CCF searched out to this many periods from lag 0
LOBE_MIN = 0.25  # tau_r + tau_l, as a share of the period: a CCF lobe, not noise
LOBE_MAX = 0.75
SIGNIFICANCE = 3.0  # the CCF extreme must reach this / sqrt(n)
ODD_PHASE = 60.0  # degrees: CCF odd enough for the stiction pattern
EVEN_PHASE = 30.0  # degrees: CCF even enough for no stiction
CURVE_FRACTION = 12.0  # curvature scale h = period / this
MIN_SNR = 3.0  # SD of the curvature over its SD from noise alone
SPIKY_KURTOSIS = 4.0  # curvature kurtosis at or above: ramps with sharp turns (stiction)
SINE_KURTOSIS = 2.25  # at or below: two-peaked, sinusoidal PV (no stiction)


@dataclasses.dataclass(frozen=True, slots=True)
class Horch:
    """Result of :func:`horch_test`.

    Self-regulating: ``phase`` (degrees, 0 even ... 90 odd), ``lag_right``/``lag_left`` (the
    CCF zero crossings either side of lag 0, samples), ``r0_ratio`` and ``r_max`` (largest
    ``|r|`` within half a period). Integrating: ``kurtosis`` of the PV curvature,
    ``sine_share`` (the two-peaked fit's sine share of its variance) and ``curvature_snr``.
    ``period`` is the one used (samples). Statistics are None when not computed.
    """

    vote: int
    note: str
    integrating: bool = False
    period: float | None = None
    phase: float | None = None
    lag_right: float | None = None
    lag_left: float | None = None
    r0_ratio: float | None = None
    r_max: float | None = None
    kurtosis: float | None = None
    sine_share: float | None = None
    curvature_snr: float | None = None

    def evidence(self) -> Evidence:
        """This result as :class:`stiction.Evidence` (value: the CCF phase in degrees, or the
        curvature kurtosis for an integrating loop)."""
        return Evidence("horch", self.kurtosis if self.integrating else self.phase,
                        self.vote, self.note)


def horch_test(op: ArrayLike, pv: ArrayLike, *, period: float | None = None,
               integrating: bool = False) -> Horch:
    """Horch's stiction test on one window of OP and PV (1-D, finite, equal length).

    ``period``: the oscillation period in samples (None: estimated from the ACF).
    ``integrating``: the process integrates (level): PV's curvature test instead of the
    cross-correlation (OP is then not used and may be constant, but must be finite). Bad
    data never raises: the vote is then 0 with a note.
    """
    if not isinstance(integrating, bool | np.bool_):
        raise ParameterError("integrating", f"must be a bool, was {integrating!r}")
    p = None if period is None else v.positive_scalar("period", period)
    u_raw = np.asarray(op, dtype=np.float64)
    y_raw = np.asarray(pv, dtype=np.float64)
    if u_raw.ndim != 1:
        raise ParameterError("op", f"must be 1-D, has ndim {u_raw.ndim}")
    if y_raw.ndim != 1:
        raise ParameterError("pv", f"must be 1-D, has ndim {y_raw.ndim}")
    if u_raw.size != y_raw.size:
        raise ParameterError("pv", f"must have the length of op ({u_raw.size}), "
                             f"has {y_raw.size}")
    integ = bool(integrating)
    for name, arr in (("OP", u_raw), ("PV", y_raw)):
        if not np.isfinite(arr).all():
            return Horch(0, f"{name} has non-finite samples", integ, p)
    y = unit_detrended(y_raw, name="PV", min_samples=MIN_SAMPLES)
    if isinstance(y, str):
        return Horch(0, y, integ, p)
    u = unit_detrended(u_raw, name="OP", min_samples=MIN_SAMPLES)
    if isinstance(u, str) and not integ:
        return Horch(0, u, integ, p)
    if p is None:
        p = _period(y_raw, None if isinstance(u, str) else u_raw, integ)
        if p is None:
            return Horch(0, "no regular oscillation: the test needs a cycle", integ)
    n = y.size
    if p < MIN_PERIOD:
        return Horch(0, f"oscillation too fast to tell: period {p:.1f} samples, the test "
                     f"needs {MIN_PERIOD:g}", integ, p)
    if n < MIN_CYCLES * p:
        return Horch(0, f"record too short to tell: {n / p:.1f} cycles, the test needs "
                     f"{MIN_CYCLES:g}", integ, p)
    if integ:
        return _curvature(y, p, _quantum(y_raw, y))
    assert not isinstance(u, str)
    return _cross_correlation(u, y, p)


def _period(pv: FloatArray, op: FloatArray | None, integrating: bool) -> float | None:
    for x in (pv,) if integrating or op is None else (pv, op):
        peak = float(np.abs(x).max())
        osc = detect_oscillation(x / peak)
        if osc.oscillating and osc.period is not None:
            return float(osc.period)
    return None


def _first_zero(s: FloatArray) -> float | None:
    """Interpolated position of the first sign change of ``s`` (s[0] at 0)."""
    sg = np.signbit(s)
    k = (sg[1:] != sg[:-1]).nonzero()[0]
    if k.size == 0:
        return None
    i = int(k[0])
    a, b = float(s[i]), float(s[i + 1])
    return i + (a / (a - b) if a != b else 0.5)


def _cross_correlation(u: FloatArray, y: FloatArray, p: float) -> Horch:
    n = u.size
    nfft = fft.next_fast_len(2 * n, real=True)
    fu, fy = fft.rfft(np.array((u, y)), nfft, axis=1)  # one FFT for both: pocketfft pairs rows
    cc = fft.irfft(np.conj(fu) * fy, nfft)  # cc[k] = sum_t u[t] y[t + k], negative k wrap
    cc = cc / math.sqrt(dot(u, u) * dot(y, y))
    reach = min(math.ceil(SEARCH * p), n - 1)
    right = cc[: reach + 1]
    left = np.concatenate((cc[:1], cc[nfft - reach :][::-1]))  # lags 0, -1, -2, ...
    half = min(int(p // 2), n - 1)
    near = np.concatenate((cc[: half + 1], cc[nfft - half :]))
    r_max = float(np.maximum.reduce(np.abs(near)))
    r0_ratio = abs(float(cc[0])) / r_max if r_max > 0 else None
    res = Horch(0, "", False, p, r_max=r_max, r0_ratio=r0_ratio)
    if r_max < SIGNIFICANCE / math.sqrt(n):
        return _say(res, 0, "OP and PV are not correlated: no pattern to read")
    tr, tl = _first_zero(right), _first_zero(left)
    if tr is None or tl is None:
        return _say(res, 0, "OP-PV cross-correlation does not cross zero near lag 0")
    width = (tr + tl) / p
    phase = 90.0 * abs(tr - tl) / (tr + tl)
    res = dataclasses.replace(res, phase=phase, lag_right=tr, lag_left=tl)
    if not LOBE_MIN <= width <= LOBE_MAX:
        return _say(res, 0, f"OP-PV cross-correlation lobe at lag 0 spans {width:.2f} "
                    "periods, not half of one")
    if phase >= ODD_PHASE:
        return _say(res, 1, f"OP-PV cross-correlation is odd (phase {phase:.0f} deg): the "
                    "stiction pattern")
    if phase <= EVEN_PHASE:
        return _say(res, -1, f"OP-PV cross-correlation is even (phase {phase:.0f} deg): no "
                    "stiction pattern")
    return _say(res, 0, f"OP-PV cross-correlation neither odd nor even (phase {phase:.0f} "
                "deg)")

def _curvature(y: FloatArray, p: float, quantum: float) -> Horch:
    h = max(1, round(p / CURVE_FRACTION))
    res = Horch(0, "", True, p)
    if y.size < 6 * h + 8:
        return _say(res, 0, "record too short for the PV curvature")
    s = ndimage.uniform_filter1d(y, h, mode="nearest") if h > 1 else y
    d = s[2 * h :] - 2.0 * s[h:-h] + s[: -2 * h]
    d = d[h:-h]
    d = d - d.mean()
    var = float((d * d).mean())
    if not var > 0:
        return _say(res, 0, "PV has no curvature")
    # white noise from second differences (blind to the trend removed from y), at least
    # the rounding noise of PV's quantum: on a quantised PV most second differences are 0
    sigma = max(noise_sd(y), quantum / math.sqrt(12.0))
    noise_d = sigma * math.sqrt(6.0 / h)
    snr = math.sqrt(var) / noise_d if noise_d > 0 else None
    kurt = float((d**4).mean()) / (var * var)
    share = min(1.0, math.sqrt(max(0.0, (3.0 - kurt) / 1.5)))
    res = dataclasses.replace(res, kurtosis=kurt, sine_share=share, curvature_snr=snr)
    if snr is not None and snr < MIN_SNR:
        return _say(res, 0, f"PV curvature is mostly noise (signal/noise {snr:.1f})")
    if kurt >= SPIKY_KURTOSIS:
        return _say(res, 1, f"PV is ramps with sharp turns (curvature kurtosis {kurt:.1f}): "
                    "the stiction pattern of a level loop")
    if kurt <= SINE_KURTOSIS:
        return _say(res, -1, f"PV curvature is two-peaked like a sine's (kurtosis "
                    f"{kurt:.1f}): no stiction pattern")
    return _say(res, 0, f"PV curvature neither spiky nor sinusoidal (kurtosis {kurt:.1f})")


def _say(res: Horch, vote: int, note: str) -> Horch:
    return dataclasses.replace(res, vote=vote, note=note)


def _quantum(raw: FloatArray, y: FloatArray) -> float:
    """PV's resolution (its smallest non-zero step, when quantised) in the units of ``y``,
    the normalised PV: ``y = (raw / peak - line) / span``, so a step of ``raw / peak`` is
    divided by ``span``, found from the second differences (blind to the line)."""
    scaled = raw / float(np.abs(raw).max())
    steps = np.abs(np.diff(scaled))
    steps = steps[steps > 0]
    if not steps.size:
        return 0.0
    d2 = np.diff(scaled, 2)
    k = int(np.abs(d2).argmax())
    if d2[k] == 0:  # a straight line: normalisation left nothing to measure
        return 0.0
    return float(steps.min()) * abs(float(np.diff(y, 2)[k] / d2[k]))


def detect(w: Window) -> Horch | Evidence:
    """``horch``: odd or even OP-PV cross-correlation (for an integrating loop PV's
    curvature), on regular cycles only (Thornhill's regularity > 1): on a loop wandering
    under random loads the cross-correlation's lobes are as likely odd as even."""
    if not w.cycle.regular:
        return Evidence("horch", None, 0, "no regular cycle to correlate")
    return horch_test(w.cycle.op.x, w.cycle.pv.x, period=w.period, integrating=w.integrating)
