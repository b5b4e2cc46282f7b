"""The Hammerstein fit of one window: validate, prepare OP and PV, search the valve
candidates coarsely, refine where it can change the vote, size and vote (see the package
doc)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..._assessment import Evidence
from ..._errors import ParameterError
from ..._validate import FloatArray
from ...signal.arrays import dot, mean, percentiles
from ...signal.noise import noise_sd
from ...signal.oscillation import detect_oscillation
from .least_squares import (
    STICKY_MAX_LAG,
    Target,
    effective_n,
    fit_rows,
    masked_min,
    period_spread,
    process_path,
    rel,
    responses,
)
from .valve import decimate, median_swing, sticky_valve, turning_points
from .vote import (
    IMPROVE_YES,
    SPREAD_YES,
    Stats,
    decide,
    swing_at_onsets,
)

__all__ = ["SAMPLES_PER_PERIOD", "HammersteinFit", "abstain", "controller_sign", "hammerstein_test"]

MAX_CYCLES = 12  # periods fitted: enough cycles for the statistics, few for speed
MIN_CYCLES = 3.0  # periods the window must hold (two full swings after the start)
MIN_PERIOD = 8.0  # samples, as stiction.signal.oscillation.MIN_PERIOD
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
SIGN_SCALE = 8  # the controller's sign from OP's change over an eighth of a period
EXTRA_PARAMETERS = 2  # S and J


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
    stats: Stats | None = None  # what the vote read (None when the fit abstained)

    def evidence(self) -> Evidence:
        """Test ``"hammerstein"``, value the improvement over the linear valve."""
        return Evidence("hammerstein", self.improvement, self.vote, self.note)


def abstain(note: str) -> HammersteinFit:
    """The fit that did not run, and why."""
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


# --- least squares over time constants and dead times ---------------------------------------


def hammerstein_test(op: FloatArray, pv: FloatArray, *, ts: float, period: float | None = None,
                     integrating: bool = False, k: float = 1.99) -> HammersteinFit:
    """Fit PV through a sticky and through a linear valve (see the package doc).

    ``op``, ``pv``: equal-length finite 1-D arrays; ``ts``: sample time (s); ``period``:
    the oscillation period in samples (None: detected on OP, then PV); ``integrating``:
    integrating process (level); ``k``: the valve's overshoot factor K in [1, 2] (He & Wang
    2014 eq 5; 1.99 for their Table 1 valve), used only to turn S and J into fs and fd."""
    ts_, k_, p = _check(ts=ts, integrating=integrating, k=k, period=period)
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ParameterError("pv", f"must be 1-D and as long as op ({pv.shape} vs {op.shape})")
    w = _prepare(op, pv, p, integrating)
    if isinstance(w, HammersteinFit):
        return w
    c = _coarse(w, integrating)
    return _result(w, c, _refine(w, c, _pick(w, c), integrating), ts=ts_, k=k_,
                   integrating=integrating)


def _check(*, ts: object, integrating: object, k: object, period: object
           ) -> tuple[float, float, float | None]:
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
    return ts_, k_, p


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """OP and PV as the fit sees them (package doc, steps 1-2): the last periods,
    block-averaged and scaled, from OP's first turning point on."""

    u: FloatArray  # OP over its 5-95 % range
    v: FloatArray  # PV likewise; its first difference for an integrating process
    piv: np.ndarray  # OP's turning points
    h: float  # the smallest reversal that counts
    swing: float  # median OP swing between turning points
    p: float  # the period in samples of the window
    q: int  # samples averaged into one
    su: float  # OP's 5-95 % range
    sv: float  # PV's
    sigma: float  # the controller's sign, 0 unknown
    lags: np.ndarray  # dead times tried, averaged samples
    target: Target

    @property
    def per(self) -> float:
        """The period in averaged samples."""
        return self.p / self.q


def _prepare(op: FloatArray, pv: FloatArray, p: float | None, integrating: bool
             ) -> _Prepared | HammersteinFit:
    """The window as the fit sees it, or a fit that abstains and says why."""
    n = op.size
    if n < 4 * SAMPLES_PER_PERIOD or not (np.isfinite(op).all() and np.isfinite(pv).all()):
        return abstain(f"window too short or not finite ({n} samples)")
    if p is None:
        for x in (op, pv):
            osc = detect_oscillation(x)
            if osc.oscillating and osc.period is not None:
                p = osc.period
                break
        if p is None:
            return abstain("no oscillation to fit")
    if p < MIN_PERIOD:
        return abstain(f"period of {p:.3g} samples: too fast to see a valve stick")
    if n < MIN_CYCLES * p:
        return abstain(f"fewer than {MIN_CYCLES:g} periods in the window")
    sigma = controller_sign(op, pv, p)
    use = int(min(n, MAX_CYCLES * p))
    q = max(1, int(p // SAMPLES_PER_PERIOD))
    u = decimate(op[n - use :], q)
    v = decimate(pv[n - use :], q)
    pu, pvr = percentiles(u, (5.0, 50.0, 95.0)), percentiles(v, (5.0, 50.0, 95.0))
    su, sv = float(pu[2] - pu[0]), float(pvr[2] - pvr[0])
    if not (su > 0 and sv > 0 and math.isfinite(su) and math.isfinite(sv)):
        return abstain("OP or PV does not move")
    u = (u - pu[1]) / su
    v = (v - pvr[1]) / sv
    h = max(H_NOISE * noise_sd(u), H_RANGE)
    swing = median_swing(u, turning_points(u, h))
    if not swing > 2.0 * h:
        return abstain("OP does not reverse beyond its noise")
    # reversals smaller than the smallest band candidate cannot move the valve: merge them
    # into the runs (the running extreme then carries OP on), which keeps the runs few
    h = max(h, MERGE * swing)
    piv = turning_points(u, h)
    if piv.size < 2 * MIN_CYCLES + 2:
        return abstain("OP does not reverse often enough beyond its noise")
    # start at OP's first turning point: the valve's state before it is unknown, and at a
    # turning point of a stick-slip cycle the valve has just slipped
    c0 = int(piv[1])
    u, v, piv = u[c0:], v[c0:], piv[1:] - c0
    swing = median_swing(u, piv)
    if integrating:
        v = v[1:] - v[:-1]
    lags = DEAD_GRID[v.size // 4 > DEAD_GRID]
    target = Target.build(v, lags)
    if not (target.svv_c > 0).all():
        return abstain("PV does not move")
    return _Prepared(u, v, piv, h, swing, p, q, su, sv, sigma, lags, target)


@dataclasses.dataclass(frozen=True)
class _Coarse:
    """Every candidate valve's fit on the coarse grid (package doc, steps 3-4)."""

    s_band: FloatArray  # the candidates' bands S and jumps J
    jump: FloatArray
    rows: FloatArray  # valve positions: row 0 the linear valve, then the candidates
    taus: FloatArray  # time constants tried, of the period
    ys: FloatArray  # the process's responses (taus, rows, samples)
    share: FloatArray  # residual shares of PV (taus, rows, lags)
    gain: FloatArray
    proc: np.ndarray  # fits through the process path
    lin_w: float  # the linear valve's best residual share, any path
    lin_c: float  # ... through the process path
    increments: float  # the sticky valve's improvement in increments (process paths)
    spread: float  # ... cycle by cycle


def _coarse(w: _Prepared, integrating: bool) -> _Coarse:
    s_band = np.repeat(S_GRID * w.swing, J_GRID.size)
    jump = s_band * np.concatenate([J_GRID] * S_GRID.size)
    keep = s_band > w.h
    s_band, jump = s_band[keep], jump[keep]
    # row 0 is the linear valve: a band of 0 belongs to the sticky family too
    rows = np.vstack((w.u[None, :], sticky_valve(w.u, w.piv, s_band, jump)))
    taus = TAU_GRID[:1] if integrating else TAU_GRID
    ys = responses(rows, w.per, integrating, taus)
    share, gain = fit_rows(w.target, ys)
    # increments: only the process path counts there (the controller's proportional kick
    # is an instantaneous relation of either sign in OP's and PV's increments)
    dlags = w.lags[w.lags <= STICKY_MAX_LAG]
    dtarget = Target.build(w.v[1:] - w.v[:-1], dlags)
    dshare, dgain = fit_rows(dtarget, ys[..., 1:] - ys[..., :-1])
    proc = process_path(gain, w.lags, w.sigma)
    dproc = process_path(dgain, dlags, w.sigma)
    lin_w = float(np.minimum.reduce(share[:, 0], axis=None))
    lin_c = masked_min(share[:, :1], proc[:, :1])
    dlin_c = masked_min(dshare[:, :1], dproc[:, :1])
    dst = masked_min(dshare, dproc)
    spread = period_spread(w.v, ys, share, proc, lags=w.lags, per=w.per, sigma=w.sigma)
    return _Coarse(s_band, jump, rows, taus, ys, share, gain, proc, lin_w, lin_c,
                   rel(dst, dlin_c), spread)


@dataclasses.dataclass(frozen=True)
class _Best:
    """The sticky candidate kept for the sizes and the level statistics, and the best
    linear valve."""

    coarse_best: float  # the process path's best residual share on the coarse grid
    ti: int  # its time constant and candidate (coarse grid)
    ci: int
    lin_ti: int  # the linear valve's time constant (coarse grid)
    rss_st: float
    rss_lin: float
    lin_y: FloatArray  # the linear valve's response at its time constant
    lag_lin: int
    best_s: float
    best_j: float
    g: float
    tau_f: float
    lag: int
    vp_best: FloatArray


def _pick(w: _Prepared, c: _Coarse) -> _Best:
    # the sticky candidate for sizes and for the level statistics: the process path's best
    # (the band trades off against the dead time - a smaller band slips earlier, a longer
    # dead time delays PV as much: of the fits near the best, take the widest band)
    sticky = np.where(c.proc[:, 1:], c.share[:, 1:], np.inf)
    best = float(sticky.min())
    if not math.isfinite(best):  # no process-path fit (sign unknown): the plain best
        sticky = c.share[:, 1:, : int(np.count_nonzero(w.lags <= STICKY_MAX_LAG))]
        best = float(sticky.min())
    near = np.argwhere(sticky <= best + SIZE_TOL * max(best, 1e-12))
    pick = near[np.lexsort((c.jump[near[:, 1]], -c.s_band[near[:, 1]]))[0]]
    ti, ci = int(pick[0]), int(pick[1])
    li = np.unravel_index(int(c.share[:, 0].argmin()), c.share[:, 0].shape)
    cj = int(sticky[ti, ci].argmin())
    return _Best(best, ti, ci, int(li[0]), rss_st=best, rss_lin=c.lin_w,
                 lin_y=c.ys[li[0], :1], lag_lin=int(w.lags[li[1]]),
                 best_s=float(c.s_band[ci]), best_j=float(c.jump[ci]),
                 g=float(c.gain[ti, ci + 1, cj]), tau_f=float(c.taus[ti]),
                 lag=int(w.lags[cj]), vp_best=c.rows[ci + 1])


def _refine(w: _Prepared, c: _Coarse, b: _Best, integrating: bool) -> _Best:
    """Finer band and jump around the kept candidate, finer time constants around its own
    (and the linear valve's) best; only where its sizes can be used (a +1 whose other
    conditions hold): elsewhere the coarse fit stands (package doc, step 7). The linear
    valve belongs to the sticky family: the process path's best of either."""
    plus = w.sigma != 0 and c.increments >= IMPROVE_YES and c.spread >= SPREAD_YES
    if plus:
        s2 = np.repeat(c.s_band[b.ci] * S_REFINE, J_REFINE.size)
        j2 = np.concatenate([c.jump[b.ci] * J_REFINE] * S_REFINE.size)
        ok2 = s2 > w.h
        s2, j2 = s2[ok2], j2[ok2]
        taus2, taus_lin = ((c.taus, c.taus) if integrating else
                           (c.taus[b.ti] * TAU_REFINE, c.taus[b.lin_ti] * TAU_REFINE))
        vp2 = sticky_valve(w.u, w.piv, s2, j2)
        share2, gain2 = fit_rows(w.target, responses(vp2, w.per, integrating, taus2))
        proc2 = process_path(gain2, w.lags, w.sigma) if w.sigma else (
            np.broadcast_to(w.lags <= STICKY_MAX_LAG, share2.shape))
        share2 = np.where(proc2, share2, np.inf)
        ys_l = responses(w.u[None, :], w.per, integrating, taus_lin)
        share_l, _ = fit_rows(w.target, ys_l)
        lj = np.unravel_index(int(share_l.argmin()), share_l.shape)
        if float(share_l[lj]) <= c.lin_w:
            b = dataclasses.replace(b, rss_lin=float(share_l[lj]), lin_y=ys_l[lj[0]],
                                    lag_lin=int(w.lags[lj[2]]))
        if float(share2.min()) < b.coarse_best:
            rss_st = float(share2.min())
            near = np.argwhere(share2 <= rss_st + SIZE_TOL * max(rss_st, 1e-12))
            sj = tuple(near[np.lexsort((j2[near[:, 1]], -s2[near[:, 1]]))[0]])
            b = dataclasses.replace(
                b, rss_st=rss_st, best_s=float(s2[sj[1]]), best_j=float(j2[sj[1]]),
                g=float(gain2[sj]), tau_f=float(taus2[sj[0]]), lag=int(w.lags[sj[2]]),
                vp_best=vp2[sj[1]])
    return dataclasses.replace(b, rss_st=min(b.rss_st, c.lin_c))


def _result(w: _Prepared, c: _Coarse, b: _Best, *, ts: float, k: float, integrating: bool
            ) -> HammersteinFit:
    """Statistics, sizes in OP units and the vote (package doc, steps 5-6)."""
    rss_st, rss_lin = b.rss_st, b.rss_lin
    n_eff = effective_n(w.target, b.lin_y, b.lag_lin)
    improvement = 1.0 - rss_st / rss_lin if rss_lin > 0 else 0.0
    delta_aic = (n_eff * math.log(max(rss_lin, 1e-300) / max(rss_st, 1e-300))
                 - 2.0 * EXTRA_PARAMETERS)
    stats = Stats(
        explained=1.0 - rss_st, level=min(improvement, rel(rss_st, c.lin_c)),
        increments=c.increments, gain=rss_lin - rss_st, spread=c.spread,
        delta_aic=delta_aic, sigma=w.sigma, explained_linear=1.0 - rss_lin,
        explained_process=1.0 - c.lin_c, level_process=rel(rss_st, c.lin_c))
    swing_he = swing_at_onsets(w.u, b.vp_best, b.lag)
    band = b.best_s if swing_he is None else swing_he
    fs = (band + b.best_j) / 2.0
    fd = max(fs - b.best_j / k, 0.0)
    su = w.su
    gain_pv = b.g * w.sv / su / (w.q * ts if integrating else 1.0)
    vote, note = decide(stats, fd * su)
    return HammersteinFit(
        rss_sticky=rss_st, rss_linear=rss_lin, improvement=improvement, delta_aic=delta_aic,
        n_eff=n_eff, fs=fs * su, fd=fd * su, band=band * su, jump=b.best_j * su, gain=gain_pv,
        tau=None if integrating else b.tau_f * w.p * ts, dead_time=b.lag * w.q * ts,
        vote=vote, note=note, stats=stats)


def controller_sign(u: FloatArray, y: FloatArray, period: float) -> float:
    """The sign of the controller's action, from its integral term: -1, +1, or 0 when the
    data cannot tell (see the module doc). ``u``: OP, ``y``: PV, ``period`` in samples."""
    lag = max(1, round(period / SIGN_SCALE))
    if u.size < 4 * lag:
        return 0.0
    du = u[lag:] - u[:-lag]
    cy = np.concatenate(([0.0], (y - mean(y)).cumsum()))
    my = (cy[lag + 1 :] - cy[1:-lag]) / lag  # mean PV over (t - lag, t]
    c = float(dot(du - mean(du), my))
    return 0.0 if c == 0 else (-1.0 if c > 0 else 1.0)


