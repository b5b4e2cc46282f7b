"""Apparent stiction from the OP-PV pattern (ellipse fit).

Reference: Choudhury, M. A. A. S., Shah, S. L., Thornhill, N. F. & Shook, D. S. (2006),
"Automatic detection and quantification of stiction in control valves", Control Engineering
Practice 14(12), 1395-1412. Once a loop is judged nonlinear, they filter OP and PV around the
oscillation frequency (a frequency-domain Wiener filter), plot filtered PV against filtered OP,
fit an ellipse, and call its width along the OP axis the *apparent stiction* (in OP units).

Algorithm as implemented (:func:`ellipse_band`):

1. OP and PV lose their mean and straight-line trend (:func:`~stiction.signal.oscillation.detrend`).
2. Band-pass, zero phase: the real FFT of each signal keeps only the frequencies within
   ``[BAND_LO, BAND_HI]`` times ``1 / period`` and is transformed back. This is the
   frequency-domain filter of the paper reduced to a rectangular pass band (our choice; the
   paper sets the band from the bicoherence peak, which this module does not compute). The
   band holds the fundamental and the third harmonic, where the stick-slip pattern lives, and
   drops drifts and noise. ``EDGE`` periods at each end, where the rectangular window rings,
   are not fitted.
3. For ``integrating=True`` the pattern is OP against dPV/dt: in an integrating process the
   rate of change of PV, not PV, follows the valve position (our reading; the paper plots
   PV for every loop). The derivative is taken in the frequency domain.
4. Direct least-squares ellipse fit (Fitzgibbon, Pilu & Fisher 1999, in the numerically
   stable form of Halir & Flusser 1998) on both signals scaled to unit standard deviation:
   the conic ``a x^2 + b xy + c y^2 + d x + e y + f = 0`` with ``4ac - b^2 = 1`` minimising
   the algebraic distance; a 3 x 3 generalised eigenproblem.
5. From the conic: the chord through the centre parallel to the OP axis (the widest one:
   horizontal chords have their midpoints on a diameter) is the apparent stiction band
   ``band`` (OP units); the filtered OP's swing, ``2 amplitude``; their ratio ``width_ratio``
   in [0, 1], which for sinusoids is ``|sin(phase)|``; ``band_share``, the share of OP's
   variance inside the pass band.
6. On the fundamental alone (``[BAND_LO, FUND_HI]`` times 1 / period): ``phase_deg``, the
   angle of the one complex gain from OP to PV that fits all frequency bins of the band best
   (0: PV in phase with OP, 180: against it), and ``coherence``, the share of PV's power in
   the band that this gain explains (1: a clean elliptic pattern; in closed loop with a
   constant setpoint it is high whatever the cause, it drops with setpoint moves, noise and
   several oscillations at once).

Vote (constants below; each stated where it comes from):

* ``0`` when the cloud admits no ellipse, when PV keeps no steady phase to OP (``coherence <
  COHERENCE_MIN``) or when the pass band holds less than ``BAND_SHARE_MIN`` of OP's
  variance: no clean pattern, no opinion.
* ``-1`` when the pattern collapses towards a line, ``|sin(phase)| < THIN``: PV moves with OP
  (or against it) at the oscillation frequency, so there is no band for the valve to stick in
  and OP does not ramp while PV waits. That is the pattern of a loop tuned too tightly
  (proportional action carries the cycle) or of a linear valve in an integrating loop.
* otherwise ``0``. **The shape cannot say +1.** With the setpoint constant, OP = -C(q) PV at
  every frequency whatever the cause, so the filtered pattern's phase is fixed by the
  controller at the oscillation frequency: a slow external disturbance, or any cycle well
  below the integral corner 1/Ti, gives the same wide ellipse as a sticky valve. The band is a
  *size* to use once other tests have called stiction (the issue's "sizes where the limit
  cycle is not clean").

What it sees and where it fails. The band of the simulated sticky flow loop of He & Wang's
Table 4 (case 2) comes out within 15 % of the OP swing between valve jumps (S = 2 fs - J,
which is 2 fd for K = 2), that of their level loop (Table 5, ``integrating=True``) within
25 %, and both scale with OP's units. It is the band seen by OP: it includes the controller's
overshoot after each jump (dead time, slow PV) and underestimates when the jump itself
carries much of OP's motion (proportional kicks). A thin ellipse is evidence against a
stick-slip cycle: in a self-regulating loop the valve sits still while integral action ramps
OP, which puts PV a quarter period or more from OP; pass ``integrating=True`` for level
loops, otherwise a sticky level loop's PV-OP pattern is thin too. THIN leaves a wide margin
between the paper's sticky loops (|sin(phase)| 0.93-1.0 in ``stiction.scenarios``) and the
simulated aggressively tuned loop (0.10-0.12). A cloud within ``LINE`` of a line is not
fitted (the algebraic fit degenerates there): its band is the fundamental's width.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import fft

from .._assessment import Evidence
from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.arrays import std
from ..signal.oscillation import detrend
from .base import NO_CYCLE, Window

__all__ = ["EllipseFit", "detect", "ellipse_band"]

BAND_LO = 0.5  # pass band, in multiples of the oscillation frequency 1 / period
BAND_HI = 3.5  # keeps the third harmonic (the square and triangle shapes), drops the fifth
EDGE = 0.5  # periods dropped at each end (rectangular-window ringing)
MIN_CYCLES = 2.5  # periods the window must hold (as stiction.signal.cycle.MIN_CYCLES)
MIN_POINTS = 16  # points for a 5-parameter conic with some to spare
MIN_PERIOD = 8.0  # samples, as stiction.signal.oscillation.MIN_PERIOD (the third harmonic needs 3)
POINTS_PER_PERIOD = 24  # the filtered signals hold nothing above 3.5 / period: fit every k-th
FUND_HI = 1.5  # the fundamental's band, for the phase and coherence
# our choices, not the paper's: below half, the pattern is mostly something else
COHERENCE_MIN = 0.5  # PV power at the fundamental one complex gain from OP must explain
BAND_SHARE_MIN = 0.3  # share of OP variance the pass band must hold (sticky loops 0.65-0.99)
THIN = 0.3  # |sin(phase)| below which the ellipse has collapsed (see the module doc)
LINE = 0.1  # |sin(phase)| below which the cloud is taken as a line, not fitted (6 degrees)


@dataclasses.dataclass(frozen=True)
class EllipseFit:
    """Apparent stiction band from the filtered OP-PV pattern (see the module doc).

    ``band`` and ``amplitude`` are in OP units; None when no ellipse was fitted.
    """

    band: float | None
    amplitude: float | None
    width_ratio: float | None
    phase_deg: float | None
    coherence: float | None
    band_share: float | None
    vote: int
    note: str

    def evidence(self) -> Evidence:
        """Test ``"ellipse"``, value the width ratio (unit-free; the band is in the note)."""
        return Evidence("ellipse", self.width_ratio, self.vote, self.note)


def _none(note: str, band_share: float | None = None) -> EllipseFit:
    return EllipseFit(None, None, None, None, None, band_share, 0, note)


def _check_period(period: object) -> float:
    if isinstance(period, bool):
        raise ParameterError("period", f"must be a number of samples, was {period!r}")
    try:
        p = float(period)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError("period", f"must be a number of samples, was {period!r}") from exc
    if not math.isfinite(p) or p <= 0.0:
        raise ParameterError("period", f"must be a finite number of samples > 0, was {period!r}")
    return p


def _spectra(u: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Real FFT of both signals at once, and the frequencies (cycles per sample)."""
    spec = fft.rfft(np.array((u, y)), axis=1)
    return np.asarray(spec), np.arange(spec.shape[1]) / u.size


def fit_conic(x: FloatArray, y: FloatArray) -> FloatArray | None:
    """Direct least-squares ellipse (Halir & Flusser 1998): coefficients (a, b, c, d, e, f)
    with 4ac - b^2 > 0, or None when the points admit no ellipse."""
    d1 = np.stack((x * x, x * y, y * y), axis=1)
    d2 = np.stack((x, y, np.ones_like(x)), axis=1)
    # einsum, not BLAS: a BLAS product over n rows goes multi-threaded on long windows and
    # costs more in thread hand-off than in arithmetic on a busy edge CPU (see _validate.dot)
    s1 = np.einsum("ni,nj->ij", d1, d1)
    s2 = np.einsum("ni,nj->ij", d1, d2)
    s3 = np.einsum("ni,nj->ij", d2, d2)
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError:
        return None
    m = s1 + s2 @ t
    # premultiply by the inverse of the constraint matrix [[0, 0, 2], [0, -1, 0], [2, 0, 0]]
    m = np.array([m[2] / 2.0, -m[1], m[0] / 2.0])
    if not np.isfinite(m).all():
        return None
    w, v = np.linalg.eig(m)
    v = np.real(v)
    cond = 4.0 * v[0] * v[2] - v[1] ** 2
    ok = np.flatnonzero((cond > 0) & (np.abs(np.imag(w)) < 1e-9 * (1 + np.abs(np.real(w)))))
    if ok.size == 0:
        return None
    a1 = v[:, ok[(np.real(w)[ok]).argmin()]]
    return np.concatenate((a1, t @ a1))


def _geometry(coef: FloatArray) -> tuple[float, float] | None:
    """(chord through the centre along x, extent along x) of the ellipse ``coef``; None when
    degenerate."""
    a, b, c, d, e, f = (float(v) for v in coef)
    den = 4.0 * a * c - b * b
    if den <= 0 or a == 0 or c == 0:
        return None
    x0 = (b * e - 2.0 * c * d) / den
    y0 = (b * d - 2.0 * a * e) / den
    f0 = a * x0 * x0 + b * x0 * y0 + c * y0 * y0 + d * x0 + e * y0 + f
    # (p - p0)^T Q (p - p0) = -f0, Q = [[a, b/2], [b/2, c]]
    lam = np.linalg.eigvalsh(np.array([[a, b / 2.0], [b / 2.0, c]]))
    if -f0 / lam[0] <= 0 or -f0 / lam[1] <= 0:
        return None
    chord = 2.0 * math.sqrt(-f0 / a)  # a (x - x0)^2 = -f0 on the line y = y0
    extent = 2.0 * math.sqrt(-f0 * 4.0 * c / den)  # max |x - x0| = sqrt(-f0 c / (ac - b^2/4))
    return chord, extent


def _checked(op: FloatArray, pv: FloatArray, period: float, integrating: bool
             ) -> tuple[float, FloatArray, FloatArray]:
    p = _check_period(period)
    if not isinstance(integrating, bool | np.bool_):
        raise ParameterError("integrating", f"must be True or False, was {integrating!r}")
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ParameterError("pv", f"must be 1-D and as long as op ({pv.shape} vs {op.shape})")
    return p, op, pv


def ellipse_band(op: FloatArray, pv: FloatArray, *, period: float,
                 integrating: bool = False) -> EllipseFit:
    """Apparent stiction band of one window (Choudhury et al. 2006; see the module doc).

    ``op``, ``pv``: equal-length finite 1-D arrays; ``period``: the oscillation period in
    samples; ``integrating``: fit OP against dPV/dt (level loops)."""
    p, op, pv = _checked(op, pv, period, integrating)
    n = op.size
    if p < MIN_PERIOD:
        return _none(f"period of {p:.3g} samples: too fast for a pattern")
    if n < max(MIN_POINTS, MIN_CYCLES * p):
        return _none(f"window too short for the pattern: {n} samples, "
                     f"fewer than {MIN_CYCLES:g} periods")
    if not (np.isfinite(op).all() and np.isfinite(pv).all()):
        return _none("non-finite samples")
    # scale first: the filters and the fit then see numbers of order one whatever the units
    r_op = float(np.maximum.reduce(op) - np.minimum.reduce(op))  # np.ptp, without its layers
    r_pv = float(np.maximum.reduce(pv) - np.minimum.reduce(pv))
    if not (r_op > 0 and r_pv > 0):
        return _none("OP or PV does not move")
    if not (math.isfinite(r_op) and math.isfinite(r_pv)):
        return _none("OP or PV beyond floating-point range")
    u = detrend((op - op[0]) / r_op)
    y = detrend((pv - pv[0]) / r_pv)
    step = max(1, int(p // POINTS_PER_PERIOD))
    su = std(u)
    sy = std(y)
    if not (su > 0 and sy > 0):
        return _none("OP or PV does not move")
    su *= r_op
    spec, f = _spectra(u * (r_op / su), y / sy)
    f0 = 1.0 / p
    if integrating:
        spec[1] *= 2j * np.pi * f
    # the fundamental: one complex gain from OP to PV across the band (coherence, phase)
    fund = (f >= BAND_LO * f0) & (f <= FUND_HI * f0)
    cu, cy = spec[0, fund], spec[1, fund]
    puu = float((np.abs(cu) ** 2).sum())
    pyy = float((np.abs(cy) ** 2).sum())
    cross = complex((cy * np.conj(cu)).sum())
    coherence = abs(cross) ** 2 / (puu * pyy) if puu > 0 and pyy > 0 else 0.0
    phase = math.degrees(abs(math.atan2(cross.imag, cross.real)))
    # the pattern: fundamental and third harmonic
    keep = (f >= BAND_LO * f0) & (f <= BAND_HI * f0)
    power = spec[0].real ** 2 + spec[0].imag ** 2
    share = float(power[keep].sum() / max(float(power[1:].sum()), 1e-300))
    kept = keep.nonzero()[0]  # one stretch of bins: zero what lies either side
    spec[:, : kept[0] if kept.size else spec.shape[1]] = 0.0
    spec[:, kept[-1] + 1 if kept.size else 0 :] = 0.0
    filt = fft.irfft(spec, n, axis=1)
    cut = int(EDGE * p)
    uf, yf = filt[0, cut : n - cut : step], filt[1, cut : n - cut : step]
    su2, sy2 = std(uf), std(yf)
    if not (su2 > 0 and sy2 > 0):
        return _none("no oscillation inside the pass band", share)
    xs, ys = uf / su2, yf / sy2
    coef = fit_conic(xs, ys)
    geo = None if coef is None else _geometry(coef)
    if coef is None or geo is None:
        return _none("the filtered OP-PV cloud admits no ellipse", share)
    chord, _ = geo
    scale = su * su2  # OP units per unit of xs
    # the swing of the filtered OP itself: a cloud that is nearly a line fits a needle-thin
    # (numerically fragile) ellipse whose ends lie far beyond the points; no chord is wider
    # than the points
    extent = float(np.maximum.reduce(xs) - np.minimum.reduce(xs))
    chord = min(chord, extent)
    thin = abs(math.sin(math.radians(phase)))
    if thin < LINE:
        chord = extent * thin  # a line: the algebraic fit degenerates; the fundamental's width
    band = chord * scale
    amplitude = extent / 2.0 * scale
    ratio = chord / extent if extent > 0 else 0.0
    if not all(math.isfinite(v) for v in (band, amplitude, ratio, coherence, phase)):
        return _none("ellipse fit did not converge", share)
    vote, note = _vote(band, ratio, coherence, phase, share)
    return EllipseFit(band, amplitude, ratio, phase, coherence, share, vote, note)


def _vote(band: float, ratio: float, coherence: float, phase: float,
          share: float) -> tuple[int, str]:
    if share < BAND_SHARE_MIN:
        return 0, (f"OP holds only {share:.0%} of its variance near the oscillation frequency: "
                   "no pattern to read")
    if coherence < COHERENCE_MIN:
        return 0, (f"PV and OP keep no steady phase at the oscillation frequency (coherence "
                   f"{coherence:.2f}): no pattern to read")
    thin = abs(math.sin(math.radians(phase)))
    if thin < THIN:
        return -1, (f"thin OP-PV ellipse (PV {phase:.0f} degrees from OP): PV moves with OP, "
                    "no stiction band")
    return 0, (f"OP-PV ellipse {ratio:.0%} wide: apparent band {band:.3g} OP units; a slow "
               "disturbance gives the same shape")


def detect(w: Window) -> EllipseFit | Evidence:
    """``ellipse``: the OP-PV pattern of the band-passed cycle; a thin ellipse (PV follows
    OP) says not stiction. Its fit also sizes the apparent stiction band."""
    if w.period is None:
        return Evidence("ellipse", None, 0, NO_CYCLE)
    return ellipse_band(w.cycle.op.x, w.cycle.pv.x, period=w.period, integrating=w.integrating)
