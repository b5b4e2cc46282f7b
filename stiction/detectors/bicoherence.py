"""Higher-order-statistics nonlinearity test (Choudhury, Shah & Thornhill).

References
----------
M. A. A. Shoukat Choudhury, S. L. Shah and N. F. Thornhill (2004), "Diagnosis of poor
control-loop performance using higher-order statistics", Automatica 40(10), 1719-1728.
M. A. A. S. Choudhury, S. L. Shah and N. F. Thornhill (2008), "Diagnosis of Process
Nonlinearities and Valve Stiction: Data Driven Approaches", Springer (chapters 3 and 6).
The significance test of a squared bicoherence is Hinich's (1982) as used there: under a
Gaussian signal ``2 K bic^2(f1, f2)`` is asymptotically chi-square with 2 degrees of freedom.

Idea
----
A linear loop driven by Gaussian noise, or rung at one frequency, has zero bispectrum: its
frequency components carry no phase coupling. A limit cycle made by a nonlinearity (a sticky
valve) has harmonics whose phases are locked to the fundamental, and the squared bicoherence

    bic^2(f1, f2) = |E[X(f1) X(f2) X*(f1+f2)]|^2 / (E[|X(f1) X(f2)|^2] E[|X(f1+f2)|^2])

is large at the coupled bifrequencies. The authors summarise it by two indices: the
non-Gaussianity index NGI (mean of the significant bic^2 minus the critical bic^2) and the
nonlinearity index NLI = max bic^2 - (robust mean + 2 robust SD) of bic^2; NGI > 0.001 is a
non-Gaussian signal, and then NLI > 0.01 a nonlinear one. The total nonlinearity index TNLI
is the sum of the significant bic^2.

Algorithm as implemented
------------------------
1. The signal (the control error, or PV detrended when there is no setpoint) is scaled by its
   own largest magnitude, its mean and least-squares line are removed, and it is scaled to
   unit peak. (Nothing below depends on units or offset.)
2. Segment length ``L``: with the oscillation period ``P`` (samples), ``L = round(c P)`` with
   ``c`` the smallest odd integer such that ``L >= MIN_SEGMENT_LENGTH``; so the fundamental
   falls on FFT bin ``c`` and its harmonics on multiples of it. ``c`` is odd because the
   segments overlap by half: the hop is ``c P / 2`` and an even ``c`` would start every
   segment at the same phase of the cycle, so that window leakage of a pure sine adds up
   coherently across segments and reads as phase coupling (measured: a noisy sine with
   ``L = 2P`` gave bic^2 0.98). Without ``P``: the authors' ``L = DEFAULT_SEGMENT_LENGTH``
   (128, the FFT length of their examples), halved (down to 32) while the record gives fewer
   than ``MIN_SEGMENTS`` segments. A period under ``MIN_PERIOD`` (4 samples: no harmonic below
   Nyquist; the ACF reports such periods on noise) or a record under 32 samples: vote 0.
3. ``K`` segments of ``L`` samples, overlapping by half (the authors' 50 %), each with its mean
   removed and a Hann window (periodic form, so its leakage vanishes at two or more bins from a
   component), FFT. Fewer than ``MIN_SEGMENTS`` (20) segments: vote 0, too short to tell (the
   chi-square null is asymptotic in ``K``; 20 is our reading of "tens of segments").
4. Band. The bispectrum is taken over its principal domain (``f1 <= f2``,
   ``f1 + f2 <= 1/2``) without the DC bin. With a period, bin 1 is ``f0 / c``: every slower
   component (drift, trend) lies below the band, which is the authors' high-pass; the upper
   edge is the ``HARMONICS``-th (32nd) harmonic (or Nyquist if lower): far above any harmonic
   a stiction cycle shows over noise, yet wide enough that most bifrequencies carry only noise,
   the background against which NLI measures a peak (with the band cut at the 10th harmonic a
   clean sawtooth filled the whole domain with coupling and read "linear"). The authors band-
   pass filter the data instead; the normalised bicoherence is unchanged by a linear filter
   except through ``epsilon``, so restricting the domain is the same operation without the
   filter's transients. Without a period: the whole principal domain.
5. bic^2 with the authors' regularisation of the denominator: ``D + epsilon`` with
   ``epsilon`` the ``EPSILON_PERCENTILE`` (75th) percentile of ``D`` over the domain, the
   conditioning factor suggested in Choudhury et al. (2008, p. 80) as read by astrochron's
   ``bicoherence`` (we could not check the book's page), and at least ``EPSILON_FLOOR``
   (1e-6) of the largest ``D`` (ours: on a noise-free sine most of the domain is rounding
   error, the percentile is then 1e-33 of the peak, and deterministic leakage 1e-11 below the
   peak read bic^2 = 1.00; 1e-6 still leaves harmonics of 1 % power untouched). It keeps
   bifrequencies with little power from producing spurious peaks; being relative, it is
   unit-free.
6. Significance. A bifrequency is significant when ``bic^2 > chi2_{2}(ALPHA / M) / (2 K)``:
   the authors' chi-square critical value at ``ALPHA = 0.05``, Bonferroni-corrected for the
   ``M`` bifrequencies tested (see "Doubt" below).
   NGI = mean of the significant bic^2 - that critical value (with none significant, the mean
   of the empty set is taken as 0, so NGI = -critical < 0: Gaussian).
   NLI = max bic^2 - (mean + 2 SD) of bic^2 without its top and bottom ``TRIM`` (10 %)
   (the authors' "robust" mean and SD; they write NLI with an absolute value, which only
   matters when the maximum is below mean + 2 SD; we keep the sign).
   TNLI = sum of the significant bic^2.
7. Third-harmonic check (ours). bic^2 is blind to cycles that are half-wave symmetric
   (``x(t + P/2) = -x(t)``: only odd harmonics, zero bispectrum): the He-model sticky loops
   of :mod:`stiction.scenarios` are exactly that, because the valve model and the linear loop
   are odd-symmetric. Their third harmonic is phase-locked to the fundamental, which the
   fourth-order analogue of bic^2 at (f0, f0, f0) sees:
   ``t^2 = |E[X(f0)^3 X*(3 f0)]|^2 / (E[|X(f0)|^6] E[|X(3 f0)|^2])``, significant above
   ``chi2_2(ALPHA / 3) / (2 K)`` under the same asymptotics. ``f0`` is bin ``c``; ``3 f0`` the
   best of bins ``3c - 1 .. 3c + 1`` (the period from the ACF can be 10-15 % off on irregular
   cycles), never bin ``c + 1``, which holds the fundamental's own window leakage (a noisy
   sine read t^2 0.96 there). ``E[|X(3 f0)|^2]`` is floored at ``THIRD_FLOOR`` (1e-4) of
   ``E[|X(f0)|^2]``, as epsilon above (a triangle's third harmonic has 1/81 of the
   fundamental's power). Only with a period.
8. Vote. NGI > ``NGI_THRESHOLD`` (0.001) and NLI > ``NLI_THRESHOLD`` (0.01): +1, nonlinear.
   Otherwise, a significant third harmonic: 0 (a symmetric non-sinusoidal cycle, which this
   test cannot judge). Otherwise -1: Gaussian (NGI <= 0.001) or non-Gaussian but linear (flat
   bicoherence, NLI <= 0.01); a limit cycle from stiction is then unlikely.

Doubt about the published decision
----------------------------------
With the per-bifrequency critical value at alpha = 0.05, about 5 % of the bifrequencies of a
Gaussian signal are "significant" and their mean exceeds the critical value by about ``1/K``
(the chi-square tail beyond any point has mean 2), so NGI of white noise is about 0.01-0.02
(measured at K = 55: 0.015-0.022), far above 0.001; and NLI of white noise is about
``(ln M - 2) / K`` (measured: 0.04-0.13, depending on epsilon), above 0.01. Read literally,
the published thresholds call white noise nonlinear. The Bonferroni correction keeps the
authors' formulas and thresholds and makes them hold: a Gaussian signal has no significant
bifrequency in about 95 % of records, so NGI < 0 and the vote is -1. Measured (see
``tests/test_detector_bicoherence.py``): white noise, AR(1) noise, noisy sines and linear
loops (aggressive tuning, sinusoidal load, random load) vote -1, except about one noisy sine
in twenty, where the third-harmonic check abstains (0); asymmetric sticky-valve loops vote +1
with NGI 0.08-0.13 and NLI 0.39-0.55.

What it sees and where it fails
-------------------------------
Sees: a nonlinear cycle with asymmetric shape (sawtooth OP, a valve that sticks more one way
than the other, a nonlinear installed characteristic) against a linear one (tuning, most
external disturbances), without any shape model. Fails: half-wave-symmetric cycles (vote 0
when the third harmonic shows it, else -1 by mistake); short records (K < 20 segments, i.e.
fewer than about 10 cycles); any nonlinearity that is not the valve (a nonlinear process, a
non-sinusoidal external disturbance, set-point steps inside the window: a step's harmonics are
phase-locked and read nonlinear).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import fft

from .. import _validate as v
from .._assessment import Evidence
from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.arrays import mean, percentiles, std, unit_detrended
from .base import NO_CYCLE, Window

__all__ = ["Bicoherence", "bicoherence_test", "detect"]

ALPHA = 0.05  # the authors' significance level for one bifrequency
NGI_THRESHOLD = 0.001  # the authors' NGI threshold: non-Gaussian above
NLI_THRESHOLD = 0.01  # the authors' NLI threshold: nonlinear above
TRIM = 0.10  # share cut from each end for the robust mean and SD of bic^2
MIN_SEGMENTS = 20  # fewer segments: too short to tell
DEFAULT_SEGMENT_LENGTH = 128  # the authors' segment (FFT) length, used without a period
MIN_SEGMENT_LENGTH = 32  # shortest segment: enough bins for a bifrequency background
EPSILON_PERCENTILE = 75.0  # conditioning factor: this percentile of the denominator ...
EPSILON_FLOOR = 1e-6  # ... and at least this share of its largest value
THIRD_FLOOR = 1e-4  # third-harmonic power floor, share of the fundamental's
HARMONICS = 32  # with a period: bifrequencies up to this harmonic of the fundamental
MIN_PERIOD = 4.0  # samples: a faster cycle has no harmonic below Nyquist
_BLOCK = 8192  # complex products per block in the bispectrum sum (128 kB)


@dataclasses.dataclass(frozen=True, slots=True)
class Bicoherence:
    """Result of :func:`bicoherence_test`.

    ``ngi``, ``nli``, ``tnli``: the authors' indices (module doc); ``max_bicoherence`` the
    largest bic^2 and ``critical`` the bic^2 a bifrequency must exceed to be significant;
    ``third_harmonic`` the squared tricoherence of the third harmonic with the fundamental
    (None without a period); ``segments``/``segment_length``/``bifrequencies`` the ``K``,
    ``L`` and ``M`` of the estimate. Statistics are None when the test could not run.
    """

    vote: int
    note: str
    ngi: float | None = None
    nli: float | None = None
    tnli: float | None = None
    max_bicoherence: float | None = None
    critical: float | None = None
    third_harmonic: float | None = None
    segments: int = 0
    segment_length: int = 0
    bifrequencies: int = 0

    def evidence(self) -> Evidence:
        """This result as :class:`stiction.Evidence` (value: NLI)."""
        return Evidence("bicoherence", self.nli, self.vote, self.note)


def bicoherence_test(x: ArrayLike, *, period: float | None = None) -> Bicoherence:
    """Choudhury et al.'s bicoherence nonlinearity test of one signal.

    ``x``: the control error (SP - PV), or PV detrended when there is no setpoint; 1-D,
    finite. ``period``: the oscillation period in samples (sets the segment length so that
    the fundamental falls on an FFT bin, and enables the third-harmonic check). Bad data
    never raises: the vote is then 0 with a note.
    """
    p = _check_period(period)
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 1:
        raise ParameterError("x", f"must be 1-D, has ndim {arr.ndim}")
    y = unit_detrended(arr, name="signal", min_samples=MIN_SEGMENT_LENGTH)
    if isinstance(y, str):
        return Bicoherence(0, y)
    if p is not None and p < MIN_PERIOD:
        return Bicoherence(0, f"oscillation too fast to tell: period {p:.1f} samples, the "
                           f"test needs {MIN_PERIOD:g}")
    n = y.size
    if p is not None:
        c = 1
        while c * p < MIN_SEGMENT_LENGTH:
            c += 2
        seg_len = round(c * p)
    else:
        c = 0
        seg_len = DEFAULT_SEGMENT_LENGTH
        while seg_len > MIN_SEGMENT_LENGTH and _count(n, seg_len) < MIN_SEGMENTS:
            seg_len //= 2
    k = _count(n, seg_len)
    if k < MIN_SEGMENTS:
        cycles = f" ({n / p:.1f} cycles)" if p is not None else ""
        return Bicoherence(
            0, f"record too short to tell: {k} segments of {seg_len} samples{cycles}, "
            f"the bicoherence needs {MIN_SEGMENTS}",
            segments=k, segment_length=seg_len)
    spec = _spectra(y, seg_len, k)
    top = spec.shape[1] - 1 if not c else min(spec.shape[1] - 1, HARMONICS * c)
    i, j = _domain(top)
    m = i.size
    b2 = _squared_bicoherence(spec, i, j)
    if b2 is None:
        return Bicoherence(0, "signal has no power to analyse", segments=k,
                           segment_length=seg_len, bifrequencies=m)
    crit = -math.log(ALPHA / m) / k  # chi-square (2 dof) upper ALPHA / m point, over 2 K
    sig = b2[b2 > crit]
    ngi = (float(sig.mean()) if sig.size else 0.0) - crit
    tnli = float(sig.sum())
    ordered = np.sort(b2)
    cut = int(TRIM * m)
    core = ordered[cut : m - cut] if m - 2 * cut >= 2 else ordered
    bmax = float(ordered[-1])
    nli = bmax - (mean(core) + 2.0 * std(core))
    third = _third_harmonic(spec, c) if c else None
    res = Bicoherence(0, "", ngi, nli, tnli, bmax, crit, third, k, seg_len, m)
    if ngi > NGI_THRESHOLD and nli > NLI_THRESHOLD:
        return _say(res, 1, f"nonlinear: phase-coupled harmonics (NLI {nli:.2f}, "
                    f"NGI {ngi:.3f})")
    if third is not None and third > -math.log(ALPHA / 3) / k:
        return _say(res, 0, "non-sinusoidal but half-wave symmetric cycle: the bicoherence "
                    "cannot judge it")
    if ngi <= NGI_THRESHOLD:
        return _say(res, -1, "linear: no significant bicoherence (Gaussian signal)")
    return _say(res, -1, f"linear: non-Gaussian but flat bicoherence (NLI {nli:.3f})")


def _say(res: Bicoherence, vote: int, note: str) -> Bicoherence:
    return dataclasses.replace(res, vote=vote, note=note)


def _check_period(period: float | None) -> float | None:
    return None if period is None else v.positive_scalar("period", period)


def _count(n: int, seg_len: int) -> int:
    """Segments of ``seg_len`` samples overlapping by half in ``n`` samples."""
    hop = max(seg_len // 2, 1)
    return 0 if n < seg_len else (n - seg_len) // hop + 1


@functools.lru_cache(maxsize=64)
def _window(seg_len: int) -> FloatArray:
    return np.asarray(0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(seg_len) / seg_len))


@functools.lru_cache(maxsize=64)
def _domain(top: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Bins (i, j) of the principal domain without DC, up to bin ``top``:
    1 <= i <= j, i + j <= top."""
    i, j = np.triu_indices(top + 1, k=0)
    keep = (i >= 1) & (i + j <= top)
    return i[keep].astype(np.intp), j[keep].astype(np.intp)


def _spectra(y: FloatArray, seg_len: int, k: int) -> NDArray[np.complex128]:
    hop = seg_len // 2
    idx = np.arange(seg_len)[None, :] + hop * np.arange(k)[:, None]
    seg = y[idx]
    seg = seg - np.add.reduce(seg, axis=1, keepdims=True) / seg_len
    return np.asarray(fft.rfft(seg * _window(seg_len), axis=1))


def _squared_bicoherence(spec: NDArray[np.complex128], i: NDArray[np.intp],
                         j: NDArray[np.intp]) -> FloatArray | None:
    k = spec.shape[0]
    pw = spec.real**2 + spec.imag**2  # (K, bins)
    pair = (pw.T @ pw)[i, j] / k  # E|X(f1) X(f2)|^2
    d = pair * (np.add.reduce(pw, axis=0) / k)[i + j]
    d_max = float(np.maximum.reduce(d))
    if not d_max > 0.0:
        return None
    # E[X(f1) X(f2) X*(f1+f2)], a block of bifrequencies at a time: whole (K, M) temporaries
    # are each allocated afresh (mmap) and cost more in page faults than the arithmetic
    by_bin = np.ascontiguousarray(spec.T)
    conj = np.conj(by_bin)
    ij = i + j
    b = np.empty(i.size, dtype=np.complex128)
    step = max(1, _BLOCK // k)
    for lo in range(0, i.size, step):
        hi = lo + step
        prod = by_bin[i[lo:hi]]
        prod *= by_bin[j[lo:hi]]
        prod *= conj[ij[lo:hi]]
        b[lo:hi] = np.add.reduce(prod, axis=1)
    b /= k
    eps = max(percentiles(d, (EPSILON_PERCENTILE,))[0], EPSILON_FLOOR * d_max)
    return np.asarray((b.real**2 + b.imag**2) / (d + eps))


def _third_harmonic(spec: NDArray[np.complex128], c: int) -> float | None:
    """Largest squared tricoherence of bins (c, c, c) with 3c - 1 .. 3c + 1 (not c + 1): the
    third harmonic's phase lock to the fundamental, allowing for an error in the period."""
    if 3 * c + 1 >= spec.shape[1]:
        return None
    x1 = spec[:, c]
    # not bin c + 1: the fundamental's own window leakage, whose cube product would stay
    # in phase from segment to segment
    x3 = spec[:, max(3 * c - 1, c + 2) : 3 * c + 2]
    p1 = x1.real**2 + x1.imag**2
    p3 = (x3.real**2 + x3.imag**2).mean(axis=0) + THIRD_FLOOR * float(p1.mean())
    den = float((p1**3).mean()) * p3
    if not (den > 0.0).all():
        return None
    num = np.abs(((x1**3)[:, None] * np.conj(x3)).mean(axis=0)) ** 2
    return float((num / den).max())


def detect(w: Window) -> Bicoherence | Evidence:
    """``bicoherence``: the nonlinearity of PV's cycle, on cycling windows only (it
    diagnoses an oscillation, and reads a set-point step's transient as nonlinear)."""
    if w.period is None:
        return Evidence("bicoherence", None, 0, NO_CYCLE)
    return bicoherence_test(w.cycle.pv.x, period=w.period)
