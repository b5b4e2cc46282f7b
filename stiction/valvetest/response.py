"""How far the valve moved at each step: its response identified, then every step's share.

The response (PV, or the valve's position where a positioner reports it) to the valve's
moves is taken as linear and the same for every move: a first-order lag ``tau`` after a
dead time ``theta`` (a self-regulating PV, or a position), or its integral (an integrating
PV: the move changes PV's rate). :func:`fit_dynamics` finds ``theta`` and ``tau`` (and,
asked to, which of the two kinds) on the steps with the largest OP changes, which surely
moved the valve; :func:`fit_moves` then writes the whole recording as a constant (and an
initial rate) plus one such response per step, of unknown size, in one least-squares fit:
a step's size is what the valve did there, even where a hold was too short for the
response to settle (its tail is in the fit), and its standard error says what noise alone
would give.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from .._validate import FloatArray
from .holds import Holds

__all__ = ["Dynamics", "Moves", "basis", "fit_dynamics", "fit_moves"]

BIG_STEPS = 6  # steps whose windows identify the dynamics


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
    per s for an integrating PV) and its standard error; the residual noise level."""

    size: FloatArray
    se: FloatArray
    noise: float
    model: FloatArray  # the fitted response, one value per sample
    columns: FloatArray  # basis of each step, samples x steps (for the timings)


def basis(t: FloatArray, theta: float | FloatArray, tau: float | FloatArray,
          integrating: bool) -> FloatArray:
    """Response at times ``t`` (s after the step) to a unit move: ``1 - exp(-(t - theta) /
    tau)`` after the dead time, or its integral (unit rate) for an integrating PV."""
    s = np.maximum(t - theta, 0.0)
    lag = -np.expm1(-s / tau)
    return s - tau * lag if integrating else lag


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
    """(first sample, step sample, end) around the steps after which the response changed
    most (its level, or its rate for an integrating PV): from the middle of the hold
    before to the end of the hold after. Large OP steps need not move a sticky valve."""
    level, rate = _hold_lines(y, holds, ts)
    change = np.abs(np.diff(rate if integrating else level))
    change = np.where(np.isfinite(change), change, -1.0)
    steps = np.argsort(-change, kind="stable")[:BIG_STEPS] + 1
    out = []
    for k in sorted(int(k) for k in steps):
        a = (holds.start[k - 1] + holds.end[k - 1]) // 2
        out.append((int(a), int(holds.step_at[k]), int(holds.end[k])))
    return out


def _rss_grid(y: FloatArray, wins: list[tuple[int, int, int]], *, ts: float,
              thetas: FloatArray, taus: FloatArray, integrating: bool) -> FloatArray:
    """Residual sum of squares, per (theta, tau) of the grid, of every window fitted alone
    (a level, a rate if integrating, the step's response), summed; the normal equations of
    the whole grid are solved at once."""
    total = np.zeros((thetas.size, taus.size))
    for a, k, b in wins:
        seg = y[a:b]
        good = np.isfinite(seg)
        t = ((np.arange(a, b) - k) * ts)[good].astype(np.float64)
        yy = seg[good]
        fixed = np.column_stack([np.ones(t.size)] + ([t - t.mean()] if integrating else []))
        cols = basis(t[:, None, None], thetas[None, :, None], taus[None, None, :],
                     integrating)  # samples x thetas x taus
        q = fixed.shape[1]
        gram = np.empty((thetas.size, taus.size, q + 1, q + 1))
        gram[..., :q, :q] = fixed.T @ fixed
        fb = np.einsum("mq,mij->ijq", fixed, cols)
        gram[..., :q, q] = fb
        gram[..., q, :q] = fb
        gram[..., q, q] = np.einsum("mij,mij->ij", cols, cols) + 1e-12
        rhs = np.empty((thetas.size, taus.size, q + 1))
        rhs[..., :q] = fixed.T @ yy
        rhs[..., q] = np.einsum("mij,m->ij", cols, yy)
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
        rss, th, ta = _grid(y, wins, ts=ts, thetas=thetas, taus=taus,
                            integrating=integrating)
        step_th, ratio = thetas[1] - thetas[0], taus[1] / taus[0]
        rss, th, ta = _grid(y, wins, ts=ts, thetas=th + step_th * np.linspace(-1, 1, 9),
                            taus=ta * ratio ** np.linspace(-1, 1, 9), integrating=integrating)
        params = len(wins) * (3 if integrating else 2) + 2
        bic = n * np.log(max(rss, 1e-300) / max(n, 1)) + params * np.log(max(n, 2))
        dyn = Dynamics(float(th), float(ta), integrating, float(np.sqrt(rss / max(n, 1))))
        if best is None or bic < best[0]:
            best = (bic, dyn)
    assert best is not None
    return best[1]


def _grid(y: FloatArray, wins: list[tuple[int, int, int]], *, ts: float,
          thetas: FloatArray, taus: FloatArray, integrating: bool
          ) -> tuple[float, float, float]:
    taus = taus[taus > 0]
    rss = _rss_grid(y, wins, ts=ts, thetas=thetas, taus=taus, integrating=integrating)
    i, j = np.unravel_index(int(np.argmin(rss)), rss.shape)
    return float(rss[i, j]), float(thetas[i]), float(taus[j])


def fit_moves(y: FloatArray, holds: Holds, ts: float, dyn: Dynamics) -> Moves:
    """Every step's response size in one least-squares fit (see the module docstring)."""
    t = np.arange(y.size) * ts
    steps = holds.step_at[1:] * ts
    cols = basis(t[:, None] - steps[None, :], dyn.theta, dyn.tau, dyn.integrating)
    lead = [np.ones(y.size)] + ([t - t[0]] if dyn.integrating else [])
    x = np.column_stack([*lead, cols])
    good = np.isfinite(y)
    xs = x[good]
    scale = np.maximum(np.sqrt(np.einsum("ij,ij->j", xs, xs)), 1e-12)  # unit columns
    xs = xs / scale
    # normal equations, Cholesky: a fraction of an SVD's time on a recording of thousands
    # of samples and hundreds of steps (the columns are unit and far from collinear)
    gram = xs.T @ xs
    gram[np.diag_indices_from(gram)] += 1e-10
    chol = scipy.linalg.cho_factor(gram, check_finite=False)
    coef = scipy.linalg.cho_solve(chol, xs.T @ y[good], check_finite=False) / scale
    model = x @ coef
    noise = _noise(y[good] - model[good])
    inv = scipy.linalg.cho_solve(chol, np.eye(gram.shape[0]), check_finite=False)
    se = noise * np.sqrt(np.maximum(np.diag(inv), 0.0)) / scale
    lead_n = len(lead)
    return Moves(coef[lead_n:], se[lead_n:], noise, model, cols)


def _noise(resid: FloatArray) -> float:
    """Robust residual SD, widened for the correlation between neighbouring samples (the
    standard error of a level assumes independent samples)."""
    if resid.size < 4:
        return float(np.std(resid)) if resid.size else 0.0
    med = float(np.median(resid))
    sd = 1.4826 * float(np.median(np.abs(resid - med)))
    d = resid - resid.mean()
    denom = float(d @ d)
    rho = float(d[1:] @ d[:-1]) / denom if denom > 0 else 0.0
    rho = min(max(rho, 0.0), 0.95)
    return sd * float(np.sqrt((1 + rho) / (1 - rho)))
