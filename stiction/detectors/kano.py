"""Stuck intervals: PV still while OP travels (Kano et al. 2004).

Reference: Kano, M., Maruta, H., Kugemoto, H. & Shimizu, K. (2004), "Practical model and
detection algorithm for valve stiction", Proceedings of the 7th IFAC Symposium on Dynamics
and Control of Process Systems (DYCOPS), Boston. A sticky valve does not move while the
controller output changes: the detection algorithm looks for the intervals where the valve
position stays constant while OP changes, and its stiction index is the share of the record
spent in such intervals (0: none, 1: always stuck). Where the valve position is not measured
the authors use the flow rate of a flow loop as its proxy; that is what PV is here.

Our reading: the paper's thresholds on the changes of OP and of the valve position are
absolute numbers chosen per loop. Here every threshold is relative to the signals' own
noise (robust SD from second differences, :func:`stiction.signal.noise.noise_sd`) or to their own
range, so a change of units changes nothing.

Algorithm as implemented (:func:`kano_test`):

1. Scale ``m`` (samples): a sixteenth of the oscillation period when one is given, else
   ``M_DEFAULT``; at least ``M_MIN``. Both signals are averaged over ``m`` samples.
2. **PV still** at sample ``t``: the means of the ``m`` samples after and before ``t`` differ
   by at most ``eps_pv = max(STILL_Z sd_pv sqrt(2 / m), STILL_RANGE range_pv)``: within
   ``STILL_Z`` standard errors of that difference under white noise, and within a small share
   of PV's 2-98 % range (so an exponential tail that has settled counts as still in noiseless
   data).
3. **Stuck interval**: a run of still samples at least ``RUN_MIN`` scales long in which
   * OP travelled: its net change (on the ``m``-sample means) is at least ``eps_op =
     max(OP_Z sd_op sqrt(2 / m), OP_RANGE range_op)``,
   * monotonically: the net change is at least ``MONOTONE`` of OP's total variation over the
     run, taken on the means of ``PARTS`` equal parts of it (integral action ramping OP
     against a stuck valve, not OP wandering; parts, so that noise does not add up),
   * with PV off its centre: the run's mean PV is at least ``OFFSET`` of PV's half range from
     the middle of PV's 2-98 % range (not the median: a limit cycle spends longer at one
     level than at the other). A valve stuck away from where it should be leaves an error
     that drives the ramp; a healthy loop holding PV on setpoint while OP drifts against a
     slow disturbance (the known false alarm of this pattern) has PV on its centre.
   * it ends in a slip: PV's mean over the second scale after the interval differs from its
     mean over the interval's last scale by at least ``SLIP`` of PV's range plus ``STILL_Z``
     standard errors of that difference (our addition: otherwise the flat top of a
     sinusoidal PV, where OP is still moving because it lags PV by a quarter period or more,
     would count as stuck; a sinusoid moves at most sin(1.5 pi / 16) = 0.29 of its range
     between means 1.5 scales apart). An interval that runs into the end of the window,
     where its slip cannot show, is not asked for one.
   * The controller acts one way: across the accepted intervals, the sign of OP's travel
     times the sign of PV's offset must be the same (the majority sign is kept; the others
     are dropped and counted).
4. ``index`` (Kano's stiction index): the share of the window spent in accepted stuck
   intervals. ``travel_share``: the share of OP's total travel (on the ``m``-sample means)
   done during them. ``band``: the median OP travel of one stuck interval (OP units), the
   OP change the valve sat through; in a fast flow loop it approaches the valve's band
   (S = 2 fs - J), less the OP travel while PV settles after each jump.

Vote: ``+1`` when at least ``MIN_INTERVALS`` intervals hold ``index >= INDEX_YES``;
``-1`` when PV is still most of the time (``still_share >= STILL_SHARE_NO``), OP travelled
well beyond its noise, and yet still intervals with OP ramping, slip or not, cover at most
``INDEX_NO`` of the window (PV stands still only when OP does); ``0``
otherwise, in particular when PV keeps moving (``still_share`` below the minimum): then PV is
no proxy for the valve position and the test cannot see a stuck valve.

What it sees and where it fails. It sees the stick phase of fast self-regulating loops
(flow, fast pressure), with or without a clean limit cycle. It is blind where PV keeps
moving while the valve is stuck: integrating processes (level: PV ramps while the valve
waits), slow processes whose PV is still relaxing when the next jump comes, and loops with
strong load disturbances. A valve that does not move at all while OP ramps (dead PV, valve
not responding) is not stick-slip: a PV that is exactly constant gives vote 0.

Constants: STILL_Z = 3 (three standard errors); SLIP from the sinusoid bound above;
STILL_RANGE, OP_RANGE, OFFSET, MONOTONE and the index thresholds were set on the simulated
loops of :mod:`stiction.scenarios`: the sticky flow and slow loops of He & Wang's Tables 4,
6 and 7 have index 0.12-0.68 in 3 to 32 intervals; healthy loops under random loads, the
sinusoidal disturbance and aggressive tuning (PV noise 0.02-0.2, 1 s and 10 s sampling,
periods detected, wrong or none) reach 0.24 with a single interval (often one the window
cuts off) and 0.11 with two, once the slip is required. Not fitted to any plant record; on
the shared plant records (information only) the slip requirement removes most of the
stick-slip windows of tag 2411FIC20102, whose PV steps are small against the PV range of a
two-hour record.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._assessment import Evidence
from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.arrays import median, percentiles
from ..signal.noise import noise_sd
from .base import LEVELS, Window

__all__ = ["Kano", "detect", "kano_test"]

M_DEFAULT = 5  # samples per scale when no period is given
M_MIN = 2  # an average needs two samples
PERIOD_SCALES = 16  # scales per period (a sixteenth: fine enough for a jump, coarse enough
#                     to average noise; the sinusoid bound of SLIP depends on it)
STILL_Z = 3.0  # standard errors: PV moved beyond noise
STILL_RANGE = 0.03  # of PV's 2-98 % range per scale
OP_Z = 5.0  # standard errors: OP travelled beyond noise (stricter than PV's still test)
OP_RANGE = 0.05  # of OP's 2-98 % range
MONOTONE = 0.7  # net OP travel / total variation (as stiction.detectors.stickslip.MONOTONE)
PARTS = 8  # parts of a run over which OP's monotony is judged
OFFSET = 0.25  # of PV's half range
SLIP = 0.3  # of PV's range: how far PV moves within two scales after a stuck interval
RUN_MIN = 2  # scales a stuck interval lasts at least
MIN_INTERVALS = 2  # one interval is one episode: the stick-slip test's job, not this one's
INDEX_YES = 0.15  # sticky simulations 0.12-0.68, see the module doc
INDEX_NO = 0.02  # ramping-while-still share at most this for -1
STILL_SHARE_MIN = 0.2  # below it PV keeps moving: no proxy for the valve
STILL_SHARE_NO = 0.5  # PV still this often, never while OP travels: vote -1
MIN_SAMPLES = 20  # below this no scale fits twice into a run


@dataclasses.dataclass(frozen=True)
class Kano:
    """Stuck intervals of one window (see the module doc). ``band`` in OP units."""

    index: float | None
    travel_share: float | None
    still_share: float | None
    intervals: int
    dropped: int
    band: float | None
    vote: int
    note: str

    def evidence(self) -> Evidence:
        """Test ``"kano"``, value Kano's index (share of the window stuck)."""
        return Evidence("kano", self.index, self.vote, self.note)


def _none(note: str, still: float | None = None) -> Kano:
    return Kano(None, None, still, 0, 0, None, 0, note)


def _scale(period: object) -> int:
    if period is None:
        return M_DEFAULT
    if isinstance(period, bool):
        raise ParameterError("period", f"must be a number of samples or None, was {period!r}")
    try:
        p = float(period)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError("period",
                             f"must be a number of samples or None, was {period!r}") from exc
    if not math.isfinite(p) or p <= 0.0:
        raise ParameterError("period", f"must be a finite number of samples > 0, was {period!r}")
    return max(M_MIN, round(p / PERIOD_SCALES))


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) of the runs of True in ``mask``."""
    m = np.concatenate(([0], mask.view(np.int8), [0]))
    d = m[1:] - m[:-1]
    return (d == 1).nonzero()[0], (d == -1).nonzero()[0]


def _arrays(op: FloatArray, pv: FloatArray) -> tuple[FloatArray, FloatArray]:
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ParameterError("pv", f"must be 1-D and as long as op ({pv.shape} vs {op.shape})")
    return op, pv


def _one_gain_sign(a: np.ndarray, b: np.ndarray, travel: FloatArray, offset: FloatArray
                   ) -> tuple[np.ndarray, np.ndarray, FloatArray, int]:
    """The stuck intervals whose OP travel and PV offset agree in sign with the majority
    (one valve has one gain sign), and how many were dropped."""
    if not a.size:
        return a, b, travel, 0
    sign = np.sign(travel) * np.sign(offset)
    major = 1.0 if np.count_nonzero(sign > 0) >= np.count_nonzero(sign < 0) else -1.0
    keep = sign == major
    return a[keep], b[keep], travel[keep], int(a.size - np.count_nonzero(keep))


def kano_test(op: FloatArray, pv: FloatArray, *, period: float | None = None,
              noise: tuple[float, float] | None = None,
              levels: tuple[tuple[float, ...], tuple[float, ...]] | None = None) -> Kano:
    """Kano et al. (2004) stuck-interval test on one window (see the module doc).

    ``op``, ``pv``: equal-length finite 1-D arrays; ``period``: the oscillation period in
    samples, when known (sets the averaging scale); ``noise``: the white-noise SDs of OP and
    PV (:func:`~stiction.signal.noise.noise_sd`), ``levels``: their 2nd, 50th and 98th
    percentiles (:attr:`~stiction.detectors.base.Window.levels`), when the caller has them."""
    m = _scale(period)
    op, pv = _arrays(op, pv)
    n = op.size
    if n < max(MIN_SAMPLES, (2 + RUN_MIN) * m):
        return _none(f"window too short: {n} samples")
    if not (np.isfinite(op).all() and np.isfinite(pv).all()):
        return _none("non-finite samples")
    # work on centred, scaled copies: thresholds are relative, so this changes no result
    # but keeps huge or tiny magnitudes away from overflow and cancellation
    po, pp = levels or (percentiles(op, LEVELS), percentiles(pv, LEVELS))
    r_op, r_pv = float(po[2] - po[0]), float(pp[2] - pp[0])
    if not (r_pv > 0 and math.isfinite(r_pv)):
        return _none("PV does not move at all: no stick-slip to see (dead sensor or valve "
                     "not responding?)")
    if not (r_op > 0 and math.isfinite(r_op)):
        return _none("OP does not move: nothing to be stuck against")
    u = (op - po[1]) / r_op
    y = (pv - 0.5 * (pp[0] + pp[2])) / r_pv  # centred on PV's mid-range
    # the noise SD scales with the signal: of the scaled copies, that of the raw signals
    sd_u, sd_y = (noise[0] / r_op, noise[1] / r_pv) if noise else (noise_sd(u), noise_sd(y))
    cu = np.concatenate(([0.0], u.cumsum()))
    cy = np.concatenate(([0.0], y.cumsum()))
    t = np.arange(m, n - m + 1)
    dy = (cy[t + m] - 2.0 * cy[t] + cy[t - m]) / m  # mean after - mean before
    eps_y = max(STILL_Z * sd_y * math.sqrt(2.0 / m), STILL_RANGE)
    still = np.abs(dy) <= eps_y
    still_share = np.count_nonzero(still) / still.size
    eps_u = max(OP_Z * sd_u * math.sqrt(2.0 / m), OP_RANGE)
    a, b = _runs(still)
    a, b = t[a], t[b - 1] + 1  # sample positions [a, b)
    long_ = (b - a) >= RUN_MIN * m
    a, b = a[long_], b[long_]
    mu = (cu[m:] - cu[:-m]) / m  # mu[t]: mean of u[t:t + m]
    # OP's total travel on m-sample means, averaged over the m phases of the grid
    total_tv = float(np.add.reduce(np.abs(mu[m:] - mu[:-m]))) / m
    if a.size:
        mu_a = mu[a]  # OP mean over the first and last scale of the run
        mu_b = mu[b - m]
        travel = mu_b - mu_a
        # monotone: OP's total variation over at most PARTS equal parts of the run (parts of
        # at least one scale), so that noise does not add up along a long run
        parts = np.minimum(np.maximum((b - a) // m, 1), PARTS)
        frac = np.minimum(np.arange(PARTS + 1)[None, :], parts[:, None]) / parts[:, None]
        pos = a[:, None] + np.rint(frac * (b - m - a)[:, None]).astype(np.intp)
        mp = mu[pos]
        tv = np.add.reduce(np.abs(mp[:, 1:] - mp[:, :-1]), axis=1)
        offset = (cy[b] - cy[a]) / (b - a)
        # the interval ends in a slip: PV's mean one to two scales later has moved away
        end = np.minimum(b + 2 * m, n)
        after = (cy[end] - cy[end - m]) / m
        unseen = b + 2 * m > n  # the window ends before a slip could show
        slip = unseen | (np.abs(after - (cy[b] - cy[b - m]) / m)
                         >= SLIP + STILL_Z * sd_y * math.sqrt(2.0 / m))
        ramp = ((np.abs(travel) >= eps_u) & (np.abs(travel) >= MONOTONE * tv)
                & (np.abs(offset) >= OFFSET * 0.5))
        ramp_share = float(((b - a)[ramp]).sum()) / n
        ok = ramp & slip
        a, b, travel, offset = a[ok], b[ok], travel[ok], offset[ok]
    else:
        travel = offset = np.empty(0)
        ramp_share = 0.0
    a, b, travel, dropped = _one_gain_sign(a, b, travel, offset)
    count = int(a.size)
    index = float((b - a).sum()) / n
    travel_share = float(np.abs(travel).sum()) / total_tv if total_tv > 0 else 0.0
    band = median(np.abs(travel)) * r_op if count else None
    moved = (float(np.maximum.reduce(u)) - float(np.minimum.reduce(u))) >= 10.0 * eps_u
    vote, note = _vote(index, count, still_share, moved and ramp_share <= INDEX_NO, band)
    return Kano(index, min(travel_share, 1.0), still_share, count, dropped, band, vote, note)


def _vote(index: float, count: int, still_share: float, never_stuck: bool,
          band: float | None) -> tuple[int, str]:
    if count >= MIN_INTERVALS and index >= INDEX_YES:
        return 1, (f"PV stood still while OP ramped in {count} intervals ({index:.0%} of the "
                   f"window; median OP travel {band:.3g}): the valve stuck")
    if still_share < STILL_SHARE_MIN:
        return 0, (f"PV keeps moving ({still_share:.0%} of samples still): PV is no proxy for "
                   "the valve position here")
    if never_stuck and index <= INDEX_NO and still_share >= STILL_SHARE_NO:
        return -1, "PV stood still only while OP did: no stuck valve seen"
    return 0, f"stuck intervals cover {index:.0%} of the window: too few to tell"


def detect(w: Window) -> Kano:
    """``kano``: stuck intervals, PV still while OP ramps, then a slip."""
    return kano_test(w.op, w.pv, period=w.period, noise=w.noise, levels=w.levels)
