"""Does a sticky valve explain PV better than a linear one? A Hammerstein fit.

References: the valve is He & Wang's semiphysical model (He & Wang 2014, "Valve stiction
quantification method based on a semiphysical valve stiction model", Ind. Eng. Chem. Res. 53,
12010-12022; parameters fs, fd, K) in the two-parameter form of Choudhury, Thornhill & Shah
(2005, "Modelling valve stiction", Control Eng. Pract. 13, 641-658; band S, jump J); the fit
of PV through a nonlinear valve and a low-order linear process against the same with a
linear valve follows the Hammerstein approach of Srinivasan, Rengaswamy, Narasimhan & Miller
(2005, Ind. Eng. Chem. Res. 44, 6719-6728), Jelali (2008, J. Process Control 18, 632-642) and
Karra & Karim (2009, Control Eng. Pract. 17, 939-950).

Model. ``PV = g G(q) valve(OP) + c + b t`` with G a unit-gain first order lag plus dead time
(``integrating=False``) or an integrator plus dead time (``integrating=True``), and either

* the sticky valve: it sticks whenever OP reverses; it slips once OP has moved ``S`` from
  that reversal (``J`` from its last slip when OP goes on the same way after a small
  reversal), jumps by ``J`` and sticks again; if OP goes on by more than ``J`` after a slip
  the valve follows it (the envelope of He's staircase of ``K (fs - fd)`` steps). With
  ``S = 2 fs - J`` and ``J = K (fs - fd)`` this is He's model in a limit cycle; or
* the linear valve: valve(OP) = OP.

Our reading, and why. He's model measures the next slip from the last *slip*; a fit of it
on a recorded OP is fragile: in a limit cycle OP turns right after each slip, so the OP swing
equals the band, and the sample-time overshoot of every real jump (up to K times one OP step)
moves the model's valve off the recorded one until it misses a slip and stays stuck. Measuring
the band from each OP reversal (Choudhury's form) forgets that drift at every reversal. The
price: the fitted band is the OP travel from the reversal to the slip, shorter than He's
slip-to-slip band by OP's overshoot after a jump, and it trades off against the dead time
(a smaller band slips earlier, a longer dead time delays PV as much). So the reported
``band`` is read as He & Wang do (eq 9, no delay shift): the OP swing between consecutive
PV onsets, the fitted valve moves shifted by the fitted dead time. J is seen only through
the valve following OP beyond a jump (otherwise g J is one product, as in He & Wang's eq
10-12 without Kp), so ``fd = (band + J) / 2 - J / K`` (nearly ``band / 2`` for K near 2)
is the reliable size, ``fs = (band + J) / 2`` less so; of equally good fits (within
``SIZE_TOL``) the widest band and then the smallest jump are kept.

Algorithm as implemented (:func:`hammerstein_test`):

1. The fit uses the last ``MAX_CYCLES`` periods of the window, block-averaged to about
   ``SAMPLES_PER_PERIOD`` samples per period; OP and PV are scaled by their 5-95 % ranges
   (statistics do not depend on units).
2. OP's turning points: reversals larger than ``h = max(H_NOISE sd, H_RANGE)`` (sd: the
   noise SD of the averaged OP by second differences), then again with ``h`` raised to
   ``MERGE`` of the median swing (reversals smaller than the smallest band candidate cannot
   move the valve, and fewer runs make the fixed point below quick); within a run OP is
   replaced by its running extreme. The fit starts at OP's first turning point, where the
   valve is taken to have just slipped (its state before the window is unknown).
3. Candidates (``S``, ``J``): ``S`` a fraction ``S_GRID`` of the median OP swing between
   turning points, ``J`` a fraction ``J_GRID`` of ``S``; the valve output of all of them is
   built at once (the stick/slip state changes only at OP reversals: the per-reversal slip
   decisions are iterated to their fixed point, usually in one or two passes, not per
   sample). The linear valve is one more row.
4. Process: time constants ``TAU_GRID`` times the period (``scipy.signal.lfilter`` on all rows
   at once; 0.01 of a period is a pure gain at this resolution, 2.5 periods stands in for an
   integrator when a level loop is analysed as self-regulating), dead times ``DEAD_GRID``
   averaged samples up to a period (by lagged cross products, one matrix product). Both
   valves get the same family. For each combination gain, offset and drift follow by least
   squares in closed form. Integrating processes are fitted on the first difference of PV
   against the valve position (the integral of a slightly wrong valve would drift away from
   PV and hide a good fit).
5. Two paths. In a closed loop OP and PV are tied twice: through the process (the valve
   moves, PV follows after the dead time, with the gain sign negative feedback needs) and
   through the controller itself (OP = C(q) (SP - PV), so PV = SP - OP / C(q): at once, with
   the opposite sign, in every loop whatever its valve does). A linear valve free to take
   any dead time and either sign fits PV through the second path, which says nothing about
   the valve: on realistic sticky loops it explained more of PV than the sticky valve did
   (58 % against 32 %), and on level loops analysed as self-regulating it explained 96 % and
   voted -1 on sticky valves. So the comparison that carries the evidence is made on the
   *process path*: gains of the sign of the controller's action and dead times under
   ``STICKY_MAX_LAG`` (0.4 period: a half-period delay would turn a sign). The controller's
   sign comes from its integral action: over a lag L (an eighth of a period,
   ``SIGN_SCALE``), OP(t) - OP(t - L) = -Kc (PV(t) - PV(t - L)) - (Kc L / Ti) m(t), m the
   mean of PV over (t - L, t] (PV about its mean, a PI controller); the covariance of the
   first term with m(t) is -Kc (c(0) - c(L)) / L, c PV's autocovariance, so both terms carry
   the sign of -Kc, whatever the process and the valve (right on every one of the 252
   development loops). The linear valve on the process
   path is one row of the sticky family (a band of 0), so there the sticky fit never explains
   less than the linear one.
6. Levels and increments. The fit is made on PV (levels: the shape of the cycle) and on its
   first difference against the valve rows' first differences (increments: when PV moves; a
   sticky valve moves PV only after its slips, a linear one with every move of OP). Slow
   loads, which dominate the levels of realistic loops, weigh little in the increments. In
   the increments only the process path counts (the controller's proportional kick is an
   instantaneous relation of either sign between OP's and PV's increments).
7. The best process-path sticky candidate is refined (band and jump on ``S_REFINE`` x
   ``J_REFINE`` around it, time constants ``TAU_REFINE`` around its own and around the
   linear valve's) only where that can change the vote: a +1 whose other conditions hold, or
   a -1 that the coarse fit would give. Elsewhere the coarse sizes stand.

Statistics: ``rss_sticky`` and ``rss_linear``, the residual mean squares as fractions of
the variance of the fitted PV (1 - R^2) of the sticky valve on the process path (linear
valve included) and of the linear valve on either path; ``improvement = 1 - rss_sticky /
rss_linear`` (negative when the controller's own relation explains PV better than any
valve through the process); ``delta_aic``, Akaike's criterion in favour of the sticky valve,
with ``n_eff`` the number of fitted samples discounted for the lag-one autocorrelation r of
the linear fit's residuals, ``n (1 - r) / (1 + r)``, and two extra parameters (S, J),
reported but not voted on (on smooth residuals r reaches 0.98 and n_eff a handful of samples
in a window of a dozen cycles). Sizes ``fs``, ``fd``, ``band``, ``jump`` in OP units;
``gain`` in PV units per OP unit; ``tau`` and ``dead_time`` in seconds.

Vote ``+1``: the controller's sign is known, and the sticky valve on the process path

* explains at least ``EXPLAINED_YES`` (half) of PV: the loads may carry the rest, not more
  (on the realistic sticky loops the true valve position explains 5-97 % of PV, half of
  them above 60 %);
* explains it better than the linear valve, on either path, by ``IMPROVE_YES`` (a fifth of
  the linear valve's residual) in levels, and at least ``GAIN_YES`` of PV's variance more
  (when a linear valve already explains 96-99 % of PV, a gain on the last few percent is a
  detail of the model: the square load through a lag of the development loops gains 1 %);
* better than the linear valve on the process path by ``IMPROVE_YES`` in increments;
* cycle after cycle: period by period, each valve with its own gain (of the process path's
  sign) and offset, and the linear one with any dead time up to a period (any phase), the
  sticky valve's median improvement is at least ``SPREAD_YES``. The valve's signature is a
  shape that repeats every cycle; a setpoint or load step happens once, and it pins the
  linear valve's gain, after which OP moving against a load while PV holds looks like a
  valve that does not move (the known false alarm below). Set on the development loops
  (a record where one jump of an upstream sticky loop gave the sticky valve 42 % keeps
  -77 % period by period; the sticky loops that vote +1 keep 17-87 %); on loops without
  stiction with a setpoint step of 2-15 % inside the window (``scenarios``: healthy,
  sinusoidal disturbance, aggressive tuning; four loads, three seeds, 1 s and 10 s) it
  leaves 4 +1 in 216 windows where the whole-window comparison gave 34 and the earlier
  version of this test 23.

Vote ``-1``: a linear valve explains at least ``EXPLAINED_NO`` of PV on either path and
``EXPLAINED_NO_PROCESS`` through the process, and the sticky valve adds at most
``IMPROVE_NO`` (half the +1 bar) in increments, where a valve's moves show, and less than
``IMPROVE_YES`` in levels, where its extra freedom takes a share of any load. ``0``
otherwise. The thresholds were set on the development loops (``realistic_loops`` seeds 1-3,
14 of each cause, both with the process type given and analysed as self-regulating): no +1
on a loop without stiction, no -1 on a sticky one; at 0.5 instead of 0.4 for the process
path two sticky level loops whose fit failed would vote -1.

The known false alarm. A healthy loop whose OP drifts against a slow disturbance while PV
holds its setpoint also fits "a valve that does not move" better than a linear valve (an
earlier attempt, docs/accuracy.md). What stands against it here: the linear drift term
takes the slow part, the sticky valve must explain half of PV, the increments (a drifting
OP moves no PV at all), and the comparison period by period (where the linear valve's gain
is not pinned by one step elsewhere in the window). Tests
hold healthy loops under random loads, sinusoidal disturbances and aggressive tuning to no
+1.

What it sees and where it fails. It sees stick-slip wherever PV responds to the valve
through a low-order process: flow loops, slow self-regulating loops, level loops (with
``integrating=True``, and often without). It cannot tell a valve from a load that ramps and
turns (triangle, sawtooth) or steps in time with OP's reversals (a square wave through a
short lag when the controller is slow), it assumes one operating point (a strongly
nonlinear process or a setpoint change inside the window spoils both fits), and it needs at
least ``MIN_CYCLES`` periods of at least ``MIN_PERIOD`` samples of the caller's period: a
stick-slip cycle much shorter than the ACF period (loads make the ACF pick a slower cycle)
is averaged away. Where loads carry more than half of PV it abstains. Sizes: fd within 20 %
and fs within 25 % on He & Wang's Table 4 case 2 (flow), within 10 % and 15 % on Table 5
case 2 (level); up to 30 % low on the slow loops of Table 6 (tau 120 s) and Table 7 (theta
35 s), where band and dead time trade off most, within 6 % at tau 390-450 s. Speed: about
1.3 ms for a window of 3,600 samples (matrix products are cut into blocks of
``PRODUCT_SIZE`` multiply-adds: OpenBLAS hands larger ones to its threads, which on a
loaded two-core machine cost up to 8 ms a call).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from ._assessment import Evidence
from ._detect import noise_sd
from ._errors import ParameterError
from ._oscillation import detect_oscillation
from ._validate import FloatArray, dot, median, percentiles

__all__ = ["HammersteinFit", "controller_sign", "hammerstein_test"]

MAX_CYCLES = 12  # periods fitted: enough cycles for the statistics, few for speed
MIN_CYCLES = 3.0  # periods the window must hold (two full swings after the start)
MIN_PERIOD = 8.0  # samples, as stiction._oscillation.MIN_PERIOD
SAMPLES_PER_PERIOD = 20  # after block averaging (a jump within a twentieth of a period)
H_NOISE = 3.0  # OP noise SDs a reversal must exceed
H_RANGE = 0.04  # of OP's 5-95 % range
MERGE = 0.28  # reversals below this share of the median swing are merged (S_GRID starts at 0.3)
S_GRID = np.array([0.3, 0.5, 0.65, 0.8, 0.9, 0.97])  # of the median OP swing
J_GRID = np.array([0.08, 0.35, 1.0])  # of S
S_REFINE = np.array([0.93, 0.965, 1.0, 1.035, 1.07])  # of the coarse band (halves its step)
J_REFINE = np.array([0.6, 1.0, 1.6])  # of the coarse jump
TAU_REFINE = np.array([0.7, 1.0, 1.4])  # of the coarse time constant
SIZE_TOL = 0.05  # fits within 5 % of the best residual count as equally good for sizing
TAU_GRID = np.array([0.01, 0.03, 0.08, 0.25, 0.8, 2.5])  # of the period
DEAD_GRID = np.array([0, 1, 2, 3, 5, 8, 11, 14, 17, 20])  # averaged samples (20: a period)
STICKY_MAX_LAG = 8  # the process path's dead time stays under 0.4 period
SIGN_SCALE = 8  # the controller's sign from OP's change over an eighth of a period
# votes (module doc: where each comes from)
EXPLAINED_YES = 0.5
IMPROVE_YES = 0.2
SPREAD_YES = 0.15
GAIN_YES = 0.02  # of PV's variance: the share the sticky valve explains beyond the linear one
EXPLAINED_NO = 0.6
EXPLAINED_NO_PROCESS = 0.4
IMPROVE_NO = 0.1
EXTRA_PARAMETERS = 2  # S and J
PRODUCT_SIZE = 300_000  # multiply-adds per matrix product (see _product)


@dataclasses.dataclass(frozen=True)
class HammersteinFit:
    """Best sticky-valve and linear-valve fits of one window (see the module doc)."""

    rss_sticky: float | None
    rss_linear: float | None
    improvement: float | None
    delta_aic: float | None
    n_eff: float | None
    fs: float | None
    fd: float | None
    band: float | None
    jump: float | None
    gain: float | None
    tau: float | None
    dead_time: float | None
    vote: int
    note: str

    def evidence(self) -> Evidence:
        """Test ``"hammerstein"``, value the improvement over the linear valve."""
        return Evidence("hammerstein", self.improvement, self.vote, self.note)


def _none(note: str) -> HammersteinFit:
    return HammersteinFit(None, None, None, None, None, None, None, None, None, None, None,
                          None, 0, note)


def _number(name: str, value: object, *, low: float) -> float:
    if isinstance(value, bool):
        raise ParameterError(name, f"must be a number, was {value!r}")
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, f"must be a number, was {value!r}") from exc
    if not math.isfinite(v) or v < low:
        raise ParameterError(name, f"must be finite and >= {low:g}, was {value!r}")
    return v


# --- OP's turning points and the valve ------------------------------------------------------


def turning_points(u: FloatArray, h: float) -> np.ndarray:
    """Indices of OP's alternating extremes with reversals of at least ``h`` (zigzag), the
    first and last sample included."""
    n = u.size
    d = np.sign(np.diff(u))
    nz = np.flatnonzero(d)
    if nz.size == 0:
        return np.array([0, n - 1])
    turn = nz[1:][d[nz[1:]] != d[nz[:-1]]]  # diff index where the direction changes
    cand = np.concatenate(([0], turn, [n - 1]))
    vals = u[cand].tolist()
    idx = cand.tolist()
    piv = [0]
    last = vals[0]
    trend = 0
    ext_i, ext_v = 0, vals[0]
    for i, v in zip(idx[1:], vals[1:], strict=True):
        if (trend >= 0 and v > ext_v) or (trend <= 0 and v < ext_v):
            ext_i, ext_v = i, v
            if trend == 0 and abs(v - last) >= h:
                trend = 1 if v > last else -1
        if (trend == 1 and ext_v - v >= h) or (trend == -1 and v - ext_v >= h):
            piv.append(ext_i)
            last, trend = ext_v, -trend
            ext_i, ext_v = i, v
    if ext_i != piv[-1]:
        piv.append(ext_i)
    if piv[-1] != n - 1:
        piv.append(n - 1)
    return np.array(piv)


def sticky_valve(u: FloatArray, piv: np.ndarray, s_band: FloatArray,
                 jump: FloatArray) -> FloatArray:
    """Valve position (rows: candidates ``s_band[i]``, ``jump[i]``) for OP ``u`` with turning
    points ``piv`` (``piv[0] == 0``), up to a constant. The window is taken to start at an
    OP turning point where the valve has just slipped (its state before is unknown)."""
    m = u.size
    ext = u[piv[1:]]
    s = np.sign(ext - u[piv[:-1]])
    s[s == 0] = 1.0
    # reversal 0 is the start, a slip the other way; reversal k + 1 ends run k
    ext_x = np.concatenate(([u[0]], ext))
    s_x = np.concatenate(([-s[0]], s))
    seg = np.zeros(m, dtype=np.intp)
    seg[piv[1:-1] + 1] = 1
    seg = np.cumsum(seg)
    st = s[seg]
    big = 4.0 * (float(np.abs(u).max()) + 1.0)
    run_ext = st * (np.maximum.accumulate(st * u + big * seg) - big * seg)
    nc, nk = s_band.size, s.size
    col = np.arange(1, nk + 1)
    sb, jb = s_band[:, None], jump[:, None]

    def refs(slip: np.ndarray) -> tuple[np.ndarray, FloatArray]:
        last = np.maximum.accumulate(np.where(slip, col, 0), axis=1)
        ref = np.concatenate((np.zeros((slip.shape[0], 1), dtype=np.intp), last[:, :-1]),
                             axis=1)
        return ref, ext_x[ref]

    slip = (s * (ext - ext_x[:-1]))[None, :] > sb
    # fixed point of the slip decisions; a row that repeats itself is final (each pass
    # settles at least one more reversal), so only the others are iterated
    todo = np.arange(nc)
    for _ in range(nk + 1):
        ref, e_ref = refs(slip[todo])
        thr = np.where(s_x[ref] == s[None, :], jb[todo], sb[todo])
        new = s[None, :] * (ext[None, :] - e_ref) > thr
        changed = np.any(new != slip[todo], axis=1)
        slip[todo] = new
        todo = todo[changed]
        if todo.size == 0:
            break
    ref, e_ref = refs(slip)
    thr = np.where(s_x[ref] == s[None, :], jb, sb)
    beyond = np.maximum(0.0, s * (ext - e_ref) - thr - jb)
    step = np.where(slip, s * (jb + beyond), 0.0)
    level = np.concatenate((np.zeros((nc, 1)), np.cumsum(step, axis=1)[:, :-1]), axis=1)
    d = st * (run_ext - e_ref[:, seg]) - thr[:, seg]
    vp = level[:, seg] + np.where(d > 0, st * (jb + np.maximum(0.0, d - jb)), 0.0)
    return np.asarray(vp)


# --- least squares over time constants and dead times ---------------------------------------


@dataclasses.dataclass(frozen=True)
class _Target:
    """The fitted PV with its lagged cross-product matrix and nuisance sums (offset, drift)
    for each dead time."""

    lags: np.ndarray
    cross: FloatArray  # (m, 2 * nlags): target and time, shifted by each lag
    n: FloatArray
    st: FloatArray
    stt: FloatArray
    sv: FloatArray
    svt: FloatArray
    det: FloatArray  # of the offset-and-drift normal equations (1 where singular)
    svv_c: FloatArray  # variance sum after removing offset and drift
    svv_d: FloatArray  # svv_c, 1 where 0 (the divisor of the residual shares)

    @classmethod
    def build(cls, v: FloatArray, lags: np.ndarray) -> _Target:
        m = v.size
        t = np.arange(m, dtype=np.float64) - 0.5 * (m - 1)
        jj = np.arange(m)[:, None] + lags[None, :]
        ok = jj < m
        jc = np.minimum(jj, m - 1)
        cross = np.concatenate((np.where(ok, v[jc], 0.0), np.where(ok, t[jc], 0.0)), axis=1)
        cv = np.concatenate(([0.0], np.cumsum(v[::-1])))  # suffix sums: sum over [d, m)
        ct = np.concatenate(([0.0], np.cumsum(t[::-1])))
        ctt = np.concatenate(([0.0], np.cumsum((t * t)[::-1])))
        cvt = np.concatenate(([0.0], np.cumsum((v * t)[::-1])))
        cvv = np.concatenate(([0.0], np.cumsum((v * v)[::-1])))
        k = m - lags
        n = k.astype(np.float64)
        st, stt, sv, svt = ct[k], ctt[k], cv[k], cvt[k]
        det = n * stt - st * st
        det = np.where(det > 0, det, 1.0)
        svv_c = cvv[k] - _proj((n, st, stt, det), sv, svt, sv, svt)
        return cls(lags, cross, n, st, stt, sv, svt, det, svv_c, np.where(svv_c > 0, svv_c, 1.0))

    def proj(self, a1: FloatArray, at: FloatArray, b1: FloatArray, bt: FloatArray) -> FloatArray:
        """The part of the cross sum of a and b that offset and drift explain."""
        return _proj((self.n, self.st, self.stt, self.det), a1, at, b1, bt)

    def fit(self, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Residual share of variance and gain of ``target ~ g y(t - lag) + c + b t`` for each
        row of ``y`` and each lag: arrays (rows, lags)."""
        m = y.shape[1]
        k = m - self.lags
        # sums over [0, m - lag): the whole row less a short tail
        width = int(self.lags.max()) if self.lags.size else 0
        tail = y[:, m - width :]
        y2 = y * y
        t1 = np.concatenate((np.cumsum(tail[:, ::-1], axis=1)[:, ::-1], np.zeros((y.shape[0], 1))),
                            axis=1)
        t2 = np.concatenate((np.cumsum(y2[:, m - width :][:, ::-1], axis=1)[:, ::-1],
                             np.zeros((y.shape[0], 1))), axis=1)
        pos = k - (m - width)
        sy = y.sum(axis=1)[:, None] - t1[:, pos]
        syy = y2.sum(axis=1)[:, None] - t2[:, pos]
        c = _product(y, self.cross)
        nl = self.lags.size
        syv, syt = c[:, :nl], c[:, nl:]
        syy_c = syy - self.proj(sy, syt, sy, syt)
        syv_c = syv - self.proj(sy, syt, self.sv, self.svt)
        ok = syy_c > 1e-9 * np.maximum(syy, 1e-300)
        g = np.where(ok, syv_c / np.where(ok, syy_c, 1.0), 0.0)
        rss = np.maximum(self.svv_c - g * syv_c, 0.0)
        return rss / self.svv_d, g


def _proj(nuisance: tuple[FloatArray, FloatArray, FloatArray, FloatArray], a1: FloatArray,
          at: FloatArray, b1: FloatArray, bt: FloatArray) -> FloatArray:
    """:meth:`_Target.proj` from the nuisance sums ``(n, st, stt, det)``."""
    n, st, stt, det = nuisance
    return np.asarray((stt * a1 * b1 - st * (a1 * bt + at * b1) + n * at * bt) / det)


def _product(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a @ b`` in blocks of at most ``PRODUCT_SIZE`` multiply-adds: small products stay
    on one thread (OpenBLAS hands larger ones to its threads, which on a loaded two-core
    machine costs milliseconds for a product of microseconds)."""
    rows = max(1, PRODUCT_SIZE // max(a.shape[1] * b.shape[1], 1))
    if a.shape[0] <= rows:
        return np.asarray(a @ b)
    return np.concatenate([a[i : i + rows] @ b for i in range(0, a.shape[0], rows)])


def _responses(vp: FloatArray, period: float, integrating: bool,
               taus: FloatArray) -> FloatArray:
    """The process model's response to each valve row, for each time constant: shape (taus,
    rows, samples); one time constant for integrating processes (whose target is PV's
    first difference)."""
    if integrating:
        return np.asarray(0.5 * (vp[:, 1:] + vp[:, :-1]))[None]
    out = np.empty((taus.size, *vp.shape))
    for y, tf in zip(out, taus, strict=True):
        a = math.exp(-1.0 / max(tf * period, 1e-3))
        y[:], _ = signal.lfilter([1.0 - a], [1.0, -a], vp, axis=1, zi=vp[:, :1] * a)
    return out


def _best(target: _Target, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Residual shares and gains of the responses ``ys`` (taus, rows, samples): shape
    (taus, rows, lags)."""
    share, g = target.fit(ys.reshape(-1, ys.shape[2]))
    return share.reshape(*ys.shape[:2], -1), g.reshape(*ys.shape[:2], -1)


def _median_swing(u: FloatArray, piv: np.ndarray) -> float:
    """Median OP swing between turning points (the partial first and last runs left out
    when there are enough)."""
    swings = np.abs(np.diff(u[piv]))
    return median(swings[1:-1] if swings.size > 3 else swings)


def _decimate(x: FloatArray, q: int) -> FloatArray:
    k = x.size // q
    return np.asarray(x[x.size - k * q :].reshape(k, q).mean(axis=1))


def hammerstein_test(op: FloatArray, pv: FloatArray, *, ts: float, period: float | None = None,
                     integrating: bool = False, k: float = 1.99) -> HammersteinFit:
    """Fit PV through a sticky and through a linear valve (see the module doc).

    ``op``, ``pv``: equal-length finite 1-D arrays; ``ts``: sample time (s); ``period``:
    the oscillation period in samples (None: detected on OP, then PV); ``integrating``:
    integrating process (level); ``k``: the valve's overshoot factor K in [1, 2] (He & Wang
    2014 eq 5; 1.99 for their Table 1 valve), used only to turn S and J into fs and fd."""
    ts_ = _number("ts", ts, low=0.0)
    if ts_ <= 0:
        raise ParameterError("ts", f"must be > 0, was {ts!r}")
    if not isinstance(integrating, bool | np.bool_):
        raise ParameterError("integrating", f"must be True or False, was {integrating!r}")
    k_ = _number("k", k, low=1.0)
    if k_ > 2.0:
        raise ParameterError("k", f"must lie in [1, 2], was {k!r}")
    p = None if period is None else _number("period", period, low=0.0)
    if p is not None and p <= 0:
        raise ParameterError("period", f"must be > 0, was {period!r}")
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ParameterError("pv", f"must be 1-D and as long as op ({pv.shape} vs {op.shape})")
    n = op.size
    if n < 4 * SAMPLES_PER_PERIOD or not (np.isfinite(op).all() and np.isfinite(pv).all()):
        return _none(f"window too short or not finite ({n} samples)")
    if p is None:
        for x in (op, pv):
            osc = detect_oscillation(x)
            if osc.oscillating and osc.period is not None:
                p = osc.period
                break
        if p is None:
            return _none("no oscillation to fit")
    if p < MIN_PERIOD:
        return _none(f"period of {p:.3g} samples: too fast to see a valve stick")
    if n < MIN_CYCLES * p:
        return _none(f"fewer than {MIN_CYCLES:g} periods in the window")
    sigma = controller_sign(op, pv, p)
    use = int(min(n, MAX_CYCLES * p))
    q = max(1, int(p // SAMPLES_PER_PERIOD))
    u = _decimate(op[n - use :], q)
    v = _decimate(pv[n - use :], q)
    pu, pvr = percentiles(u, (5.0, 50.0, 95.0)), percentiles(v, (5.0, 50.0, 95.0))
    su, sv = float(pu[2] - pu[0]), float(pvr[2] - pvr[0])
    if not (su > 0 and sv > 0 and math.isfinite(su) and math.isfinite(sv)):
        return _none("OP or PV does not move")
    u = (u - pu[1]) / su
    v = (v - pvr[1]) / sv
    per = p / q
    h = max(H_NOISE * noise_sd(u), H_RANGE)
    swing = _median_swing(u, turning_points(u, h))
    if not swing > 2.0 * h:
        return _none("OP does not reverse beyond its noise")
    # reversals smaller than the smallest band candidate cannot move the valve: merge them
    # into the runs (the running extreme then carries OP on), which keeps the runs few
    h = max(h, MERGE * swing)
    piv = turning_points(u, h)
    if piv.size < 2 * MIN_CYCLES + 2:
        return _none("OP does not reverse often enough beyond its noise")
    # start at OP's first turning point: the valve's state before it is unknown, and at a
    # turning point of a stick-slip cycle the valve has just slipped
    c0 = int(piv[1])
    u, v, piv = u[c0:], v[c0:], piv[1:] - c0
    swing = _median_swing(u, piv)
    if integrating:
        v = np.diff(v)
    lags = DEAD_GRID[v.size // 4 > DEAD_GRID]
    target = _Target.build(v, lags)
    if not (target.svv_c > 0).all():
        return _none("PV does not move")

    s_band = np.repeat(S_GRID * swing, J_GRID.size)
    jump = s_band * np.tile(J_GRID, S_GRID.size)
    keep = s_band > h
    s_band, jump = s_band[keep], jump[keep]
    # row 0 is the linear valve: a band of 0 belongs to the sticky family too
    rows = np.vstack((u[None, :], sticky_valve(u, piv, s_band, jump)))
    taus = TAU_GRID[:1] if integrating else TAU_GRID
    ys = _responses(rows, per, integrating, taus)
    share, gain = _best(target, ys)
    # increments: only the process path counts there (the controller's proportional kick
    # is an instantaneous relation of either sign in OP's and PV's increments)
    dlags = lags[lags <= STICKY_MAX_LAG]
    dtarget = _Target.build(np.diff(v), dlags)
    dshare, dgain = _best(dtarget, np.diff(ys, axis=2))
    proc = _process_path(gain, lags, sigma)
    dproc = _process_path(dgain, dlags, sigma)
    lin_w, lin_c = float(share[:, 0].min()), _masked_min(share[:, :1], proc[:, :1])
    dlin_c = _masked_min(dshare[:, :1], dproc[:, :1])
    dst = _masked_min(dshare, dproc)

    # the sticky candidate for sizes and for the level statistics: the process path's best
    # (the band trades off against the dead time - a smaller band slips earlier, a longer
    # dead time delays PV as much: of the fits near the best, take the widest band)
    sticky = np.where(proc[:, 1:], share[:, 1:], np.inf)
    best = float(sticky.min())
    if not math.isfinite(best):  # no process-path fit (sign unknown): the plain best
        sticky = share[:, 1:, : int(np.count_nonzero(lags <= STICKY_MAX_LAG))]
        best = float(sticky.min())
    near = np.argwhere(sticky <= best + SIZE_TOL * max(best, 1e-12))
    pick = near[np.lexsort((jump[near[:, 1]], -s_band[near[:, 1]]))[0]]
    ti, ci = int(pick[0]), int(pick[1])

    li = np.unravel_index(int(share[:, 0].argmin()), share[:, 0].shape)
    rss_lin, lag_lin = lin_w, int(lags[li[1]])
    lin_y = ys[li[0], :1]  # the linear valve's response at its time constant
    cj = int(sticky[ti, ci].argmin())
    rss_st = best
    best_s, best_j = float(s_band[ci]), float(jump[ci])
    g, tau_f, lag = float(gain[ti, ci + 1, cj]), float(taus[ti]), int(lags[cj])
    vp_best = rows[ci + 1]
    increments = _rel(dst, dlin_c)
    spread = _spread(v, ys, share, proc, lags=lags, per=per, sigma=sigma)
    # refine: finer band and jump around that candidate, finer time constants around its own
    # (and the linear valve's) best; only where it can change the vote (a +1 whose other
    # conditions hold, a -1 the coarse fit would give): elsewhere the coarse sizes stand
    plus = sigma != 0 and increments >= IMPROVE_YES and spread >= SPREAD_YES
    minus = (1.0 - lin_c >= EXPLAINED_NO_PROCESS and increments <= IMPROVE_NO
             and _rel(min(best, lin_c), lin_c) < IMPROVE_YES)
    if plus or minus:
        s2 = np.repeat(s_band[ci] * S_REFINE, J_REFINE.size)
        j2 = np.tile(jump[ci] * J_REFINE, S_REFINE.size)
        ok2 = s2 > h
        s2, j2 = s2[ok2], j2[ok2]
        taus2, taus_lin = ((taus, taus) if integrating else
                           (taus[ti] * TAU_REFINE, taus[li[0]] * TAU_REFINE))
        vp2 = sticky_valve(u, piv, s2, j2)
        share2, gain2 = _best(target, _responses(vp2, per, integrating, taus2))
        proc2 = _process_path(gain2, lags, sigma) if sigma else (
            np.broadcast_to(lags <= STICKY_MAX_LAG, share2.shape))
        share2 = np.where(proc2, share2, np.inf)
        ys_l = _responses(u[None, :], per, integrating, taus_lin)
        share_l, _ = _best(target, ys_l)
        lj = np.unravel_index(int(share_l.argmin()), share_l.shape)
        if float(share_l[lj]) <= lin_w:
            rss_lin, lin_y, lag_lin = float(share_l[lj]), ys_l[lj[0]], int(lags[lj[2]])
        if float(share2.min()) < best:
            rss_st = float(share2.min())
            near = np.argwhere(share2 <= rss_st + SIZE_TOL * max(rss_st, 1e-12))
            sj = tuple(near[np.lexsort((j2[near[:, 1]], -s2[near[:, 1]]))[0]])
            best_s, best_j = float(s2[sj[1]]), float(j2[sj[1]])
            g, tau_f, lag = float(gain2[sj]), float(taus2[sj[0]]), int(lags[sj[2]])
            vp_best = vp2[sj[1]]
    # the linear valve belongs to the sticky family: the process path's best of either
    rss_st = min(rss_st, lin_c)

    n_eff = _effective_n(target, lin_y, lag_lin)
    improvement = 1.0 - rss_st / rss_lin if rss_lin > 0 else 0.0
    delta_aic = (n_eff * math.log(max(rss_lin, 1e-300) / max(rss_st, 1e-300))
                 - 2.0 * EXTRA_PARAMETERS)
    stats = _Stats(
        explained=1.0 - rss_st, level=min(improvement, _rel(rss_st, lin_c)),
        increments=increments, gain=rss_lin - rss_st, spread=spread,
        delta_aic=delta_aic, sigma=sigma, explained_linear=1.0 - rss_lin,
        explained_process=1.0 - lin_c, level_process=_rel(rss_st, lin_c))
    swing_he = _swing_at_onsets(u, vp_best, lag)
    band = best_s if swing_he is None else swing_he
    fs = (band + best_j) / 2.0
    fd = max(fs - best_j / k_, 0.0)
    gain_pv = g * sv / su / (q * ts_ if integrating else 1.0)
    vote, note = _vote(stats, fd * su)
    return HammersteinFit(
        rss_sticky=rss_st, rss_linear=rss_lin, improvement=improvement, delta_aic=delta_aic,
        n_eff=n_eff, fs=fs * su, fd=fd * su, band=band * su, jump=best_j * su, gain=gain_pv,
        tau=None if integrating else tau_f * p * ts_, dead_time=lag * q * ts_, vote=vote,
        note=note)


def controller_sign(u: FloatArray, y: FloatArray, period: float) -> float:
    """The sign of the controller's action, from its integral term: -1, +1, or 0 when the
    data cannot tell (see the module doc). ``u``: OP, ``y``: PV, ``period`` in samples."""
    lag = max(1, round(period / SIGN_SCALE))
    if u.size < 4 * lag:
        return 0.0
    du = u[lag:] - u[:-lag]
    cy = np.concatenate(([0.0], np.cumsum(y - y.mean())))
    my = (cy[lag + 1 :] - cy[1:-lag]) / lag  # mean PV over (t - lag, t]
    c = float(dot(du - du.mean(), my))
    return 0.0 if c == 0 else (-1.0 if c > 0 else 1.0)


def _process_path(gain: FloatArray, lags: np.ndarray, sigma: float) -> np.ndarray:
    """Fits that go through the process: a gain of the sign negative feedback needs and a
    dead time under ``STICKY_MAX_LAG``; none when the controller's sign is unknown."""
    short = (lags <= STICKY_MAX_LAG)[None, None, :]
    return np.asarray((gain * sigma > 0) & short)


def _masked_min(share: FloatArray, mask: np.ndarray) -> float:
    return float(np.min(np.where(mask, share, np.inf), initial=np.inf))


def _rel(rss_a: float, rss_b: float) -> float:
    """Relative improvement of a fit with residual ``rss_a`` over one with ``rss_b``."""
    if not (math.isfinite(rss_a) and math.isfinite(rss_b)) or rss_b <= 0:
        return -math.inf
    return 1.0 - rss_a / rss_b


def _residual(target: FloatArray, y: FloatArray, lag: int) -> FloatArray:
    """Residual of ``target ~ g y(t - lag) + c + b t`` (least squares)."""
    m = target.size
    yy, vv = y[: m - lag], target[lag:]
    t = np.arange(vv.size, dtype=np.float64)
    return _fit_residual(yy, vv, t)


def _spread(target: FloatArray, ys: FloatArray, share: FloatArray, mask: np.ndarray,
            *, lags: np.ndarray, per: float, sigma: float) -> float:
    """Period by period, the process path's best sticky valve against the linear valve
    with the same time constant and any dead time up to a period (any phase), each with its
    own gain (of the process path's sign) and offset in every period: the median of the
    relative improvements (-inf when either fit is missing)."""
    st = np.where(mask[:, 1:], share[:, 1:], np.inf)
    li = np.where(mask[:, :1], share[:, :1], np.inf)
    if not (np.isfinite(st.min()) and np.isfinite(li.min())):
        return -math.inf
    i = np.unravel_index(int(st.argmin()), st.shape)
    j = np.unravel_index(int(li.argmin()), li.shape)
    start = int(lags.max())
    m = target.size
    v = target[start:]
    nb = max(1, round(v.size / per))
    edges = np.linspace(0, v.size, nb + 1).astype(np.intp)[:-1]
    cnt = np.diff(np.append(edges, v.size)).astype(np.float64)
    sv, svv = np.add.reduceat(v, edges), np.add.reduceat(v * v, edges)
    vvc = svv - sv * sv / cnt

    def rss(y: FloatArray) -> FloatArray:
        """Per period (columns), for each row of ``y``."""
        sy, syy = np.add.reduceat(y, edges, axis=1), np.add.reduceat(y * y, edges, axis=1)
        syv = np.add.reduceat(y * v, edges, axis=1)
        yyc, yvc = syy - sy * sy / cnt, syv - sy * sv / cnt
        g = np.where(yyc > 0, yvc / np.where(yyc > 0, yyc, 1.0), 0.0)
        g = np.where(g * sigma > 0, g, 0.0)
        return np.asarray(np.maximum(vvc - g * yvc, 0.0))

    # row 0 the sticky valve at its dead time, then the linear valve at every dead time
    lag_s = int(lags[i[2]])
    shifted = np.lib.stride_tricks.sliding_window_view(ys[j[0]][0], v.size)[start - lags]
    r = rss(np.vstack((ys[i[0]][i[1] + 1][start - lag_s : m - lag_s], shifted)))
    r_st, r_li = r[0], r[1:].min(axis=0)
    ok = r_li > 0
    if not ok.any():
        return -math.inf
    return median(1.0 - r_st[ok] / r_li[ok])


@dataclasses.dataclass(frozen=True)
class _Stats:
    """What the vote reads (see the module doc)."""

    explained: float  # share of PV the process path's sticky valve explains
    level: float  # its improvement over either linear valve, in levels
    increments: float  # ... in increments, over the process path's linear valve
    gain: float  # share of PV's variance it explains beyond the linear valve (levels)
    spread: float  # ... without the period where it gains most (process paths, both)
    delta_aic: float
    sigma: float  # the controller's sign, 0 unknown
    explained_linear: float  # share of PV the best linear valve (any path) explains
    explained_process: float  # ... the linear valve through the process path
    level_process: float  # the process path's sticky valve over its linear one, levels


def _swing_at_onsets(u: FloatArray, vp: FloatArray, lag: int) -> float | None:
    """Median OP swing between consecutive valve moves of opposite direction, OP read at
    each move's centre (weighted by the movement) shifted by the fitted dead time, that is at
    PV's onsets: He & Wang's eq 9 read at the fitted jumps, without a delay shift. A move is
    a run of samples in which the fitted valve goes one way (a jump, and the following of OP
    that the fit may add to it). None when fewer than two swings."""
    dv = np.diff(vp)
    idx = np.flatnonzero(np.abs(dv) > 1e-9 * float(np.max(np.abs(dv), initial=0.0)))
    if idx.size < 3:
        return None
    sign = np.sign(dv[idx])
    new = np.concatenate(([True], (np.diff(idx) > 1) | (sign[1:] != sign[:-1])))
    run = np.cumsum(new) - 1
    w = np.abs(dv[idx])
    centre = np.bincount(run, w * idx) / np.bincount(run, w)
    onset = np.rint(centre).astype(np.intp) + 1 + lag
    run_sign = sign[new]
    ok = onset < u.size
    onset, run_sign = onset[ok], run_sign[ok]
    alt = run_sign[1:] != run_sign[:-1]
    swings = np.abs(np.diff(u[onset]))[alt]
    return median(swings) if swings.size >= 2 else None


def _fit_residual(y: FloatArray, v: FloatArray, t: FloatArray) -> FloatArray:
    """Residual of ``v ~ g y + c + b t`` by least squares (y and t first made orthogonal
    to the constant and to each other: three small sums, no LAPACK call)."""
    tc = t - t.mean()
    vc = v - v.mean()
    stt = float(dot(tc, tc))
    bt = float(dot(vc, tc)) / stt if stt > 0 else 0.0
    yc = y - y.mean()
    yt = float(dot(yc, tc)) / stt if stt > 0 else 0.0
    yc = yc - yt * tc
    vc = vc - bt * tc
    syy = float(dot(yc, yc))
    g = float(dot(yc, vc)) / syy if syy > 1e-12 * max(float(dot(y, y)), 1e-300) else 0.0
    return np.asarray(vc - g * yc)


def _effective_n(target: _Target, y: FloatArray, lag: int) -> float:
    """Samples of the linear fit discounted for its residuals' lag-one autocorrelation."""
    m = y.shape[1]
    yy = y[0, : m - lag]
    t = np.arange(lag, m, dtype=np.float64)
    vv = target.cross[: m - lag, int(np.flatnonzero(target.lags == lag)[0])]
    r = _fit_residual(yy, vv, t)
    den = float(dot(r, r))
    rho = float(dot(r[1:], r[:-1])) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return float(r.size * (1.0 - rho) / (1.0 + rho))


def _vote(st: _Stats, fd: float) -> tuple[int, str]:
    if (st.sigma != 0 and st.explained >= EXPLAINED_YES and st.level >= IMPROVE_YES
            and st.gain >= GAIN_YES and st.increments >= IMPROVE_YES
            and st.spread >= SPREAD_YES):
        return 1, (f"a sticky valve (fd {fd:.3g} OP units) explains {st.explained:.0%} of PV, "
                   f"a linear one {max(st.explained_linear, 0.0):.0%}; better in levels "
                   f"({st.level:.0%}) and in increments ({st.increments:.0%}), cycle after "
                   "cycle")
    if (st.explained_linear >= EXPLAINED_NO and st.explained_process >= EXPLAINED_NO_PROCESS
            and st.increments <= IMPROVE_NO and st.level_process < IMPROVE_YES):
        return -1, (f"a linear valve explains {st.explained_linear:.0%} of PV "
                    f"({st.explained_process:.0%} through the process); a sticky one adds "
                    "nothing")
    why = ("the controller's sign is unclear" if st.sigma == 0 else
           f"better in levels by {max(st.level, -9.99):.0%}, in increments by "
           f"{max(st.increments, -9.99):.0%}, without its best cycle by "
           f"{max(st.spread, -9.99):.0%}")
    return 0, (f"sticky valve {max(st.explained, 0.0):.0%} of PV explained, linear "
               f"{max(st.explained_linear, 0.0):.0%}: not decisive ({why})")
