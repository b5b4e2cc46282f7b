"""How far the valve moved at each step: its response identified, then every step's share.

The response (PV, or the valve's position where a positioner reports it) to the valve's
moves is taken as linear and the same for every move: a first-order lag ``tau`` after a
dead time ``theta`` (a self-regulating PV, or a position), or its integral (an integrating
PV: the move changes PV's rate). A step is the OP path it took (an operator's ramp is a
row of small steps, :meth:`.Holds.path`). :func:`fit_dynamics` finds ``theta`` and ``tau``
(and, asked to, which of the two kinds) on the steps with the largest OP changes, which
surely moved the valve, each window fitted with the tail of the step before it (holds as
short as the process's lag leave one); :func:`fit_moves` then writes the whole recording
as a constant (and an initial rate), the settling of a move made just before the
recording began (a loop put in manual while PV still moved, or a first step at its first
sample), and one such response per step, of unknown size, in one least-squares fit: a
step's size is what the valve did there, even where a hold was too short for the response
to settle (its tail is in the fit). Its standard error says what the noise *around that
step* would give: the residual of the two holds it joins, where the model misfits them,
not only the recording's noise.

A hold in which PV moved while OP stood still by more than :data:`DISTURBED_SD` noise
standard deviations (RMS of the residual), by more than :data:`DISTURBED_SHARE` of what
the fit itself moved there and :data:`DISTURBED_NEAR` of what it moved in the two holds
before and in the one after (a misfit of a move's response spills over), and by more
than :data:`DISTURBED_FLOOR` of the largest change the fit made over any hold (the
model's misfit grows with it), was disturbed (a load change, an upset: not the valve); it
is left out of the fit (refitted without its samples) and named, and the two steps beside
it cannot be read (``disturbed``). The samples of a ramped step (OP on its way) are left
out too: the valve moved somewhere on the ramp, and a second column of the step (the
response to a move an instant earlier) takes up when. The noise is never taken below
what the recording's digits can show (:func:`recorded_step`): a signal written with four
decimals, or as float32, has that much noise even where it has none of its own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .._validate import FloatArray
from .holds import Holds

__all__ = ["Dynamics", "Moves", "basis", "fit_dynamics", "fit_moves", "recorded_step",
           "step_column"]

BIG_STEPS = 6  # steps whose windows identify the dynamics
DISTURBED_SD = 4.0
"""A hold whose residual RMS exceeds this many noise SDs (and :data:`DISTURBED_SHARE` ...)"""
DISTURBED_SHARE = 0.25
"""... of the fitted response's own change over that hold, :data:`DISTURBED_NEAR` ..."""
DISTURBED_NEAR = 0.1
"""... of its change over the two holds before and the one after, and
:data:`DISTURBED_FLOOR` ..."""
DISTURBED_FLOOR = 0.01
"""... of its largest change over any hold) was disturbed."""


@dataclasses.dataclass(frozen=True)
class Dynamics:
    """The response to a unit move: dead time and lag in s, which kind, and the fit's
    residual standard deviation."""

    theta: float
    tau: float
    integrating: bool
    rms: float


@dataclasses.dataclass(frozen=True)
class Moves:
    """Per step (``Holds`` step k at index k - 1): the response's size (response units,
    per s for an integrating PV) and its standard error; the residual noise level; the
    settling at the start (response units, as a step's size) and the disturbed holds."""

    size: FloatArray
    se: FloatArray
    noise: float  # the residual's robust SD, widened for neighbouring samples' correlation
    model: FloatArray  # the fitted response, one value per sample
    columns: FloatArray  # basis of each step, samples x steps (for the timings)
    settle: float = 0.0
    settle_se: float = 0.0
    disturbed: NDArray[np.bool_] = dataclasses.field(
        default_factory=lambda: np.zeros(0, bool))  # per hold


def basis(t: FloatArray, theta: float | FloatArray, tau: float | FloatArray,
          integrating: bool) -> FloatArray:
    """Response at times ``t`` (s after the step) to a unit move: ``1 - exp(-(t - theta) /
    tau)`` after the dead time, or its integral (unit rate) for an integrating PV."""
    s = np.maximum(t - theta, 0.0)
    lag = -np.expm1(-s / tau)
    return s - tau * lag if integrating else lag


def _path(holds: Holds, k: int) -> tuple[NDArray[np.intp], FloatArray]:
    """Step ``k``'s samples and shares; step 0 is the move just before the recording (at
    its first sample), whose settling the first hold may show."""
    return holds.path(k) if k >= 1 else (np.zeros(1, np.intp), np.ones(1))


def step_column(t: FloatArray, holds: Holds, k: int, *, ts: float,
                theta: float | FloatArray, tau: float | FloatArray, integrating: bool
                ) -> FloatArray:
    """The response at times ``t`` (s from the first sample; any shape that broadcasts
    with ``theta`` and ``tau``) to step ``k`` of unit size, along the path OP took."""
    at, w = _path(holds, k)
    out: FloatArray = w[0] * basis(t - at[0] * ts, theta, tau, integrating)
    for a, share in zip(at[1:], w[1:], strict=True):
        out = out + share * basis(t - a * ts, theta, tau, integrating)
    return out


def _hold_lines(y: FloatArray, holds: Holds, ts: float) -> tuple[FloatArray, FloatArray]:
    """Level and rate of the second half of every hold (NaN where it holds no numbers)."""
    level, rate = np.full(holds.n, np.nan), np.full(holds.n, np.nan)
    for k, (a, b) in enumerate(zip(holds.start, holds.end, strict=True)):
        seg = y[(a + b) // 2:b]
        good = np.isfinite(seg)
        if good.sum() >= 2:
            t = np.flatnonzero(good) * ts
            rate[k], level[k] = np.polyfit(t - t.mean(), seg[good], 1)
    return level, rate


def _windows(y: FloatArray, holds: Holds, ts: float, integrating: bool
             ) -> list[tuple[int, int, int]]:
    """(first sample, step, end) around the steps after which the response changed most
    (its level, or its rate for an integrating PV): from the start of the hold before to
    the end of the hold after. Large OP steps need not move a sticky valve."""
    level, rate = _hold_lines(y, holds, ts)
    change = np.abs(np.diff(rate if integrating else level))
    change = np.where(np.isfinite(change), change, -1.0)
    steps = np.argsort(-change, kind="stable")[:BIG_STEPS] + 1
    out = []
    for k in sorted(int(k) for k in steps):
        out.append((int(holds.start[k - 1]), k, int(holds.end[k])))
    return out


def _rss_grid(y: FloatArray, holds: Holds, wins: list[tuple[int, int, int]], *, ts: float,
              thetas: FloatArray, taus: FloatArray, integrating: bool) -> FloatArray:
    """Residual sum of squares, per (theta, tau) of the grid, of every window fitted alone
    (a level, a rate if integrating, the tail of the step before, the step's response),
    summed; the normal equations of the whole grid are solved at once."""
    total = np.zeros((thetas.size, taus.size))
    th, ta = thetas[None, :, None], taus[None, None, :]
    for a, k, b in wins:
        seg = y[a:b]
        good = np.isfinite(seg)
        t = (np.arange(a, b) * ts)[good].astype(np.float64)
        yy = seg[good]
        fixed = np.column_stack([np.ones(t.size)] + ([t - t.mean()] if integrating else []))
        cols = np.stack([step_column(t[:, None, None], holds, j, ts=ts, theta=th, tau=ta,
                                     integrating=integrating)
                         for j in (k - 1, k)], axis=-1)  # samples x thetas x taus x 2
        q, m = fixed.shape[1], cols.shape[-1]
        gram = np.empty((thetas.size, taus.size, q + m, q + m))
        gram[..., :q, :q] = fixed.T @ fixed
        fb = np.einsum("sq,sijm->ijqm", fixed, cols)
        gram[..., :q, q:] = fb
        gram[..., q:, :q] = np.swapaxes(fb, -1, -2)
        gram[..., q:, q:] = np.einsum("sijm,sijn->ijmn", cols, cols) + 1e-12 * np.eye(m)
        rhs = np.empty((thetas.size, taus.size, q + m))
        rhs[..., :q] = fixed.T @ yy
        rhs[..., q:] = np.einsum("sijm,s->ijm", cols, yy)
        coef = np.linalg.solve(gram, rhs[..., None])[..., 0]
        total += np.maximum(float(yy @ yy) - np.einsum("ijp,ijp->ij", coef, rhs), 0.0)
    return total


def fit_dynamics(y: FloatArray, holds: Holds, ts: float, kinds: tuple[bool, ...]
                 ) -> Dynamics:
    """Dead time and lag (and the kind, of ``kinds``: False self-regulating, True
    integrating) that fit the largest steps best; two kinds are told apart by the
    Bayesian information criterion."""
    hold_s = float(np.median(holds.end - holds.start)) * ts
    best: tuple[float, Dynamics] | None = None
    for integrating in kinds:
        wins = _windows(y, holds, ts, integrating)
        n = sum(int(np.isfinite(y[a:b]).sum()) for a, _k, b in wins)
        thetas = np.arange(-ts, max(0.5 * hold_s, 2 * ts), max(ts, hold_s / 60.0))
        taus = np.geomspace(0.2 * ts, max(2.0 * hold_s, ts), 32)
        rss, th, ta = _grid(y, holds, wins, ts=ts, thetas=thetas, taus=taus,
                            integrating=integrating)
        step_th, ratio = thetas[1] - thetas[0], taus[1] / taus[0]
        rss, th, ta = _grid(y, holds, wins, ts=ts, thetas=th + step_th * np.linspace(-1, 1, 9),
                            taus=ta * ratio ** np.linspace(-1, 1, 9), integrating=integrating)
        params = len(wins) * (4 if integrating else 3) + 2
        bic = n * np.log(max(rss, 1e-300) / max(n, 1)) + params * np.log(max(n, 2))
        dyn = Dynamics(float(th), float(ta), integrating, float(np.sqrt(rss / max(n, 1))))
        if best is None or bic < best[0]:
            best = (bic, dyn)
    assert best is not None
    return best[1]


def _grid(y: FloatArray, holds: Holds, wins: list[tuple[int, int, int]], *, ts: float,
          thetas: FloatArray, taus: FloatArray, integrating: bool
          ) -> tuple[float, float, float]:
    taus = taus[taus > 0]
    rss = _rss_grid(y, holds, wins, ts=ts, thetas=thetas, taus=taus, integrating=integrating)
    i, j = np.unravel_index(int(np.argmin(rss)), rss.shape)
    return float(rss[i, j]), float(thetas[i]), float(taus[j])


def fit_moves(y: FloatArray, holds: Holds, ts: float, dyn: Dynamics) -> Moves:
    """Every step's response size in one least-squares fit (see the module docstring), the
    disturbed holds left out."""
    t: FloatArray = np.arange(y.size, dtype=np.float64) * ts
    cols = np.column_stack([step_column(t, holds, k, ts=ts, theta=dyn.theta, tau=dyn.tau,
                                        integrating=dyn.integrating)
                            for k in range(holds.n)])  # column 0: the settling
    lead = [np.ones(y.size)] + ([t - t[0]] if dyn.integrating else [])
    good = np.isfinite(y)
    if _settled(np.column_stack(lead)[good], cols[good, 0]):
        cols[:, 0] = 0.0  # a response complete by the first sample shows no settling
    ramps = [k for k in range(1, holds.n) if holds.start[k] > holds.step_at[k]]
    for k in ramps:  # OP on its way: the valve moved somewhere on it
        good[holds.step_at[k]:holds.start[k]] = False
    when = np.column_stack([_when(t, holds.start[k] * ts, dyn) for k in ramps]
                           ) if ramps else np.zeros((y.size, 0))
    x = np.column_stack([*lead, cols, when])
    floor = recorded_step(y) / np.sqrt(12.0)  # the noise of rounding to what was recorded
    fit = _Fit.of(x, y, good, floor)
    disturbed = _disturbed(y - fit.model, fit, holds, good)
    if disturbed.any():
        for h in np.flatnonzero(disturbed):
            good[holds.start[h]:holds.end[h]] = False
        fit = _Fit.of(x, y, good, floor)
    # each step's noise: the recording's, or the residual of the two holds it joins
    local = _hold_rms(y - fit.model, holds, good) * (fit.noise / fit.sd if fit.sd > 0
                                                      else 1.0)
    noise = np.maximum(fit.noise, np.maximum(local[:-1], local[1:]))
    n, m = len(lead), holds.n
    size = fit.coef[n + 1:n + m]
    shape = cols[:, 1:].copy()  # each step's response as fitted, its timing included
    for k, b in zip(ramps, fit.coef[n + m:], strict=True):
        if size[k - 1] != 0:
            shape[:, k - 1] += b / size[k - 1] * when[:, ramps.index(k)]
    return Moves(size, fit.inv_se[n + 1:n + m] * noise, fit.noise, fit.model, shape,
                 float(fit.coef[n]), float(fit.inv_se[n] * max(fit.noise, local[0])),
                 disturbed)


def _when(t: FloatArray, end: float, dyn: Dynamics) -> FloatArray:
    """How a move's response changes when the move comes a little earlier: after a ramped
    step (ending at ``end``, s) the valve may have moved anywhere on it. The response to a
    unit move less that to one an instant later: the lag's decay after the dead time (an
    integrating PV: its rate's rise, a lasting offset of its level)."""
    s = np.maximum(t - end - dyn.theta, 0.0)
    decay = np.where(t - end - dyn.theta >= 0.0, np.exp(-s / dyn.tau), 0.0)
    out: FloatArray = -np.expm1(-s / dyn.tau) if dyn.integrating else decay
    return out


def _settled(lead: FloatArray, col: FloatArray) -> bool:
    """Whether the settling column is (nearly) the lead's: its part the constant (and the
    initial rate) do not explain is below a thousandth of it."""
    coef, *_ = np.linalg.lstsq(lead, col, rcond=None)
    rest = col - lead @ coef
    return bool(float(rest @ rest) <= 1e-6 * max(float(col @ col), 1e-300))


@dataclasses.dataclass(frozen=True)
class _Fit:
    """Least squares of the response on the design's columns over the good samples."""

    coef: FloatArray
    model: FloatArray  # at every sample
    noise: float  # widened (:func:`_noise`)
    sd: float  # the residual's robust SD
    inv_se: FloatArray  # each coefficient's standard error per unit noise

    @classmethod
    def of(cls, x: FloatArray, y: FloatArray, good: NDArray[np.bool_], floor: float) -> _Fit:
        xs = x[good]
        scale = np.maximum(np.sqrt(np.einsum("ij,ij->j", xs, xs)), 1e-12)  # unit columns
        xs = xs / scale
        # normal equations, Cholesky: a fraction of an SVD's time on a recording of
        # thousands of samples and hundreds of steps (unit columns, far from collinear)
        gram = xs.T @ xs
        gram[np.diag_indices_from(gram)] += 1e-10
        chol = scipy.linalg.cho_factor(gram, check_finite=False)
        coef = scipy.linalg.cho_solve(chol, xs.T @ y[good], check_finite=False) / scale
        model = x @ coef
        noise, sd = (max(z, floor) for z in _noise(y[good] - model[good]))
        inv = scipy.linalg.cho_solve(chol, np.eye(gram.shape[0]), check_finite=False)
        return cls(coef, model, noise, sd, np.sqrt(np.maximum(np.diag(inv), 0.0)) / scale)


def recorded_step(y: FloatArray) -> float:
    """The finest step the recording can show: the last decimal its numbers were written
    with (a historian's export, a CSV of six significant digits), or float32's precision
    (a PLC's register), whichever is coarser."""
    v = y[np.isfinite(y)][:: max(1, int(np.isfinite(y).sum()) // 2000)]
    if v.size == 0:
        return 0.0
    places = 0
    for d in range(13):
        if np.all(np.abs(np.round(v, d) - v) <= 1e-9 * 10.0 ** -d):
            break
        places = d + 1
    return max(10.0 ** -places if places < 13 else 0.0,
               float(np.finfo(np.float32).eps) * float(np.max(np.abs(v))))


def _hold_rms(resid: FloatArray, holds: Holds, good: NDArray[np.bool_]) -> FloatArray:
    """Residual RMS of every hold over its good samples (0 where it has none)."""
    out = np.zeros(holds.n)
    for h, (a, b) in enumerate(zip(holds.start, holds.end, strict=True)):
        r = resid[a:b][good[a:b]]
        if r.size:
            out[h] = float(np.sqrt(np.mean(r * r)))
    return out


def _disturbed(resid: FloatArray, fit: _Fit, holds: Holds, good: NDArray[np.bool_]
               ) -> NDArray[np.bool_]:
    """The holds whose residual is far beyond the noise and beyond the fit's own change
    over them (module docstring); none where more than a quarter of them would be (then
    the model, not the plant, misfits)."""
    rms = _hold_rms(resid, holds, good)
    # the fit's change over each hold, from the sample before it (an instant move shows
    # between the two); a misfit of a move's response spills into the next two holds and,
    # through the fit, into the hold before
    change = np.array([float(np.ptp(fit.model[max(a - 1, 0):b])) if b > a else 0.0
                       for a, b in zip(holds.start, holds.end, strict=True)])
    near = np.maximum.reduce([np.r_[0.0, change[:-1]], np.r_[0.0, 0.0, change[:-2]],
                              np.r_[change[1:], 0.0]])
    out = ((rms > DISTURBED_SD * fit.sd) & (rms > DISTURBED_SHARE * change)
           & (rms > DISTURBED_NEAR * near) & (rms > DISTURBED_FLOOR * float(change.max())))
    return out if out.sum() <= holds.n // 4 else np.zeros(holds.n, bool)


def _noise(resid: FloatArray) -> tuple[float, float]:
    """Robust residual SD widened for the correlation between neighbouring samples (the
    standard error of a level assumes independent samples), and the SD itself."""
    if resid.size < 4:
        sd0 = float(np.std(resid)) if resid.size else 0.0
        return sd0, sd0
    med = float(np.median(resid))
    sd = 1.4826 * float(np.median(np.abs(resid - med)))
    d = resid - resid.mean()
    denom = float(d @ d)
    rho = float(d[1:] @ d[:-1]) / denom if denom > 0 else 0.0
    rho = min(max(rho, 0.0), 0.95)
    return sd * float(np.sqrt((1 + rho) / (1 - rho))), sd
