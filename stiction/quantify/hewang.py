"""Stiction size from OP and PV (He & Wang 2014, section 3.1), plus the multi-jump check.

All of it rests on the limit cycle of a sticky valve that jumps once per half cycle: VP is a
rectangular wave of height J = K (fs - fd) (eq 7), switching at the PV onsets found by
:mod:`stiction.signal.switching`, each delayed by the dead time ``delay`` after the jump.

fd (eq 9, delay-shifted). The valve jumps at ``onset - delay``. Under He's model, just after
a jump the net force is u - x = fs - J, and the next jump (the other way) comes at
u - x = -fs, so the OP swing between consecutive jump points is exactly
``S = 2 fs - J`` (= 2 fd for K = 2, eq 8). We read OP at the jump points themselves - both
ends of the swing shifted back by the delay - which keeps the estimate unbiased when OP does
not turn at the jump (slow processes). Then ``fs = (S + J) / 2`` and ``fd = fs - J / K``; with
``kp`` unknown we fall back to eq 8, ``fd = S / 2`` (exact for K = 2; for K = 1.99 the bias is
(2 - K) (fs - fd) / 2, a twentieth of a percent of fd in the paper's cases).

J from PV, self-regulating (eqs 10-12): in each half cycle PV relaxes exponentially towards
its steady state ``a_k = y_base + kp x_k``, so ``J_k = |a_k - a_(k-1)| / kp``. This is eq 12's
superposition of step responses with every earlier step included, not just the last three.
Integrating (eqs 13-20): the PV slope in each half cycle is ``kp (x_k - x_balance)``, so
``J_k = |slope_k - slope_(k-1)| / kp`` (eq 19 with J in place of 2 (fs - fd): we use K, not
2, so that fs = fd + J / K holds for both process types).

Averages over half cycles are 10 %-trimmed means.

Sampling: the valve moves only at sample instants, so with OP ramping at r per sample the net
force passes fs by r/2 on average before the jump; that inflates J and fs (not fd) and is
subtracted from fs and K r/2 from J (r from a straight line through the last six OP samples
before each jump); fd = fs - J/K is unaffected.

Multi-jump check (Figure 7): a half cycle in which the valve jumps twice does not follow a
single exponential (or ramp). We flag a half cycle when splitting it in two curves (same
tau) is significant (F > 25) and the step at the split goes the same way as the half cycle's
jump and is at least a quarter of a typical jump; or when two consecutive jumps go the same
way (a missed switch). More than a quarter of flagged half cycles sets ``multi_jump``.

Fit check. A half cycle whose fit residual RMS exceeds both three times the PV noise SD and
5 % of the PV swing does not follow one valve jump's response. That is not a second jump
(plant PV often creeps between jumps), so it does not set ``multi_jump``; but in more than a
quarter of the half cycles it sets ``poor_fit`` (their count), and :func:`analyze` then does
not call the window stiction: random loads through a healthy loop make such half cycles too
(on the false-alarm benchmark this check alone keeps 12 of 540 windows from a false
``stiction``), and the creeping sticky valve of plant record 2111FIC46005 pays for it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray
from ..signal.arrays import mean, median, percentiles
from ..signal.noise import noise_sd
from ..signal.segments import closed_rss, ragged, row_chunks
from ..signal.switching import Switches, find_switches

__all__ = ["Quantification", "quantify"]

TRIM = 0.1
RESID_NOISE_FACTOR = 3.0
RESID_SWING_FRACTION = 0.05
MULTI_JUMP_FRACTION = 0.25
F_SPLIT = 25.0
SECOND_STEP_FRACTION = 0.25


@dataclasses.dataclass(frozen=True)
class Quantification:
    """Sizes in OP units; ``reason`` set when quantification could not run."""

    fd_op: float | None = None
    fs_op: float | None = None
    jump_op: float | None = None
    cycles_used: int = 0
    multi_jump: bool = False
    poor_fit: int = 0  # half cycles whose PV does not follow one jump's response
    reason: str | None = None
    warnings: tuple[str, ...] = ()
    switches: Switches | None = None
    jump_times: FloatArray | None = None  # sample positions of the valve jumps


def _mean(x: FloatArray) -> float:
    """10 %-trimmed mean (as ``scipy.stats.trim_mean``: ``int(TRIM n)`` cut from each end)."""
    if x.size < 5:
        return mean(x)
    cut = int(TRIM * x.size)
    return mean(np.sort(x)[cut : x.size - cut])


def _overshoot(op: FloatArray, jumps: FloatArray) -> float:
    """Mean excess of the net force over fs at the jumps: the valve only moves at sample
    instants, so a ramping OP passes fs by half an OP step per sample on average."""
    n = np.minimum(np.maximum(np.rint(jumps).astype(np.intp), 5), op.size - 1)
    win = n[:, None] + np.arange(-5, 1)[None, :]
    seg = op[win]
    t = np.arange(-5, 1) + 2.5
    slope = (seg - seg.mean(axis=1, keepdims=True)) @ t / float(t @ t)
    return 0.5 * float(np.abs(slope).mean())


def _second_steps(
    y: FloatArray, i: np.ndarray, j: np.ndarray, tau: float | None, *, margin: int
) -> FloatArray:
    """Is there a second valve jump inside each half cycle ``y[i[k]:j[k]]``?

    Compares the one-curve fit with the best two-curve fit (same tau, split anywhere at
    least ``margin`` samples from the ends): when the split is significant (F > F_SPLIT)
    the result is the change of the steady state (self-regulating) or slope (integrating)
    at the split, else NaN. Sums over the left pieces are prefix sums and over the right
    pieces suffix sums, so neither suffers cancellation; the basis is referenced to the
    middle of each half cycle (a scale factor, which the 2-parameter fit does not see).
    Half cycles as rows of zero-padded matrices, a few thousand entries at a time.
    """
    out = np.full(i.size, np.nan)
    n = j - i
    ks = (n >= 2 * margin + 8).nonzero()[0]
    if ks.size == 0:
        return out
    ks = ks[n[ks].argsort(kind="stable")]  # similar lengths together: little padding
    i, n = i[ks], n[ks]
    for sl in row_chunks(n):
        out[ks[sl]] = _split_rows(y, i[sl], n[sl], tau, margin)
    return out


def _split_rows(y: FloatArray, i: np.ndarray, n: np.ndarray, tau: float | None,
                margin: int) -> FloatArray:
    """:func:`_second_steps` for a chunk of half cycles ``y[i[k]:i[k] + n[k]]``.

    Cumulative sums run only over the columns that need them: the count, and for a ramp
    basis the sums of t and t^2, are closed forms (exact: small integers and halves)."""
    idx, mask = ragged(i, n)
    nf = n.astype(np.float64)[:, None]
    h = nf / 2.0
    t = (idx - i[:, None]) - h
    yy = np.where(mask, y[idx], 0.0)
    yy = np.where(mask, yy - (np.add.reduce(yy, axis=1) / n)[:, None], 0.0)
    if tau is None:
        cols = np.array((yy, yy * t, yy * yy))
    else:
        # planes g, g^2, y, y g, y^2; the padding is zero in y already, so only g needs the mask
        g = np.exp(np.minimum(np.maximum(-t / tau, -300.0), 300.0))
        cols = np.empty((5, *yy.shape))
        np.multiply(g, mask, out=cols[0])
        np.multiply(g, g, out=cols[1])
        cols[1] *= mask
        cols[2] = yy
        np.multiply(yy, g, out=cols[3])
        np.multiply(yy, yy, out=cols[4])
    # side[:, 0]: sums over [0, c] (prefix); side[:, 1]: over [c + 1, n) (suffix, one column
    # on, so that both sides of the split before column c + 1 share an index); one
    # closed-form fit for both
    w_all = idx.shape[1]
    side = np.empty((cols.shape[0], 2, *yy.shape))
    cols.cumsum(axis=2, out=side[:, 0])
    cols[..., :0:-1].cumsum(axis=2, out=side[:, 1, :, w_all - 2 :: -1])
    side[:, 1, :, -1] = 0.0
    width = w_all - 2 * margin
    c = np.arange(margin, margin + width, dtype=np.float64)[None, :]  # split: [0, c), [c, n)
    mc = c < nf - margin
    sums = side[..., margin - 1 : margin - 1 + width]
    one = side[:, 0, :, -1:]  # padding adds zeros: the sums over [0, n)
    count = np.empty((2, *yy.shape[:1], width))
    count[0] = c
    count[1] = nf - c
    if tau is None:
        t1 = c * ((c - 1.0) / 2.0 - h)  # sum of t over [0, c)
        t2 = (c - 1.0) * c * (2.0 * c - 1.0) / 6.0 - h * (c - 1.0) * c + c * h * h
        t1_all = -h  # over [0, n): n ((n - 1) / 2 - h)
        t2_all = (nf - 1.0) * nf * (2.0 * nf - 1.0) / 6.0 - h * (nf - 1.0) * nf + nf * h * h
        r, a, b = closed_rss((count, np.array(np.broadcast_arrays(t1, t1_all - t1)),
                              np.array(np.broadcast_arrays(t2, t2_all - t2)), *sums))
        r_one, _, _ = closed_rss((nf, t1_all, t2_all, *one))
    else:
        r, a, b = closed_rss((count, *sums))
        r_one, _, _ = closed_rss((nf, *one))
    r_left, r_right = r
    two = np.where(mc, r_left + r_right, np.inf)
    rows = np.arange(two.shape[0])
    k = two.argmin(axis=1)
    rss2 = two[rows, k]
    f = (r_one[:, 0] - rss2) / 2.0 / np.maximum(rss2 / (n - 4), 1e-300)
    # the change at the split: of the slope (ramp) or of the steady state (exponential)
    lev = b if tau is None else a
    step = lev[1, rows, k] - lev[0, rows, k]
    return np.asarray(np.where(f >= F_SPLIT, step, np.nan))


def quantify(
    op: FloatArray,
    pv: FloatArray,
    *,
    period: float,
    ts: float,
    kp: float | None,
    delay: float,
    integrating: bool,
    k: float,
    pv_noise: float | None = None,
) -> Quantification:
    """Estimate fd, fs (OP units) from a window already judged sticky; ``pv_noise``: PV's
    white-noise SD (:func:`~stiction.signal.noise.noise_sd`), when the caller has it."""
    sw = find_switches(pv, period, integrating=integrating)
    if sw is None or sw.onsets.size < 3:
        return Quantification(reason="fewer than three PV switching points found")
    idx = np.arange(op.size, dtype=np.float64)
    jumps = sw.onsets - delay / ts
    ok = jumps >= 0
    if np.count_nonzero(ok) < 3:
        return Quantification(reason="the delay puts the valve jumps before the window start",
                              switches=sw)
    u = np.interp(jumps[ok], idx, op)
    swing = _mean(np.abs(u[1:] - u[:-1]))

    # jump sizes between consecutive half cycles, PV units (per sample for integrators)
    lev = sw.b if integrating else sw.a
    dj = lev[1:] - lev[:-1]
    warnings: list[str] = []

    # multi-jump check: a significant second step the same way inside a half cycle, or two
    # consecutive jumps the same way; a poor single-curve fit is counted apart (poor_fit, see
    # the module doc): PV that creeps between jumps has not jumped twice
    sigma = noise_sd(pv) if pv_noise is None else pv_noise
    p5, p95 = percentiles(pv, (5.0, 95.0))
    swing_pv = float(p95 - p5)
    rms = np.sqrt(sw.rss / np.maximum(sw.count, 1.0))
    poor_fit = rms > np.maximum(RESID_NOISE_FACTOR * sigma, RESID_SWING_FRACTION * swing_pv)
    second = np.zeros(sw.a.size, dtype=bool)
    if dj.size:
        typical = median(np.abs(dj))
        c = np.floor(sw.onsets).astype(np.intp) + 1
        step = _second_steps(pv, c[:-1], c[1:], sw.tau, margin=max(5, int(0.02 * period)))
        main = np.concatenate(([-dj[0]], dj))[: sw.a.size]
        second = (np.sign(step) == np.sign(main)) & (np.abs(step) >= SECOND_STEP_FRACTION
                                                     * typical)
    same_dir = np.zeros(sw.a.size, dtype=bool)
    if dj.size >= 2:
        same = np.sign(dj[1:]) == np.sign(dj[:-1])
        same_dir[1:-1] |= same
    flagged = second | same_dir
    multi = bool(flagged.mean() > MULTI_JUMP_FRACTION) if flagged.size else False
    if flagged.any():
        warnings.append(f"{int(flagged.sum())} of {flagged.size} half cycles show a second "
                        "valve jump")
    n_poor = int(poor_fit.sum()) if poor_fit.mean() > MULTI_JUMP_FRACTION else 0

    jump_op: float | None = None
    fs_op: float | None = None
    if kp is not None and dj.size >= 1:
        per_s = ts if integrating else 1.0
        jump_raw = _mean(np.abs(dj)) / per_s / abs(kp)
        eps = min(_overshoot(op, jumps[ok]), 0.5 * jump_raw / k)
        fs_op = (swing + jump_raw) / 2.0 - eps
        jump_op = jump_raw - k * eps
        fd_op = fs_op - jump_op / k
    else:
        fd_op = swing / 2.0
    if fd_op <= 0.0:
        # fd = S / 2 - J (2 - K) / (2 K) <= 0 needs J >= K S / (2 - K) (199 S for K = 1.99),
        # or an OP swing of ~0: the PV switching points found are not where the valve jumped
        return Quantification(reason=f"inconsistent sizes (fd {fd_op:.3g} <= 0 from an OP "
                                     f"swing of {swing:.3g}): the PV switching points found "
                                     "are not valve jumps", warnings=tuple(warnings),
                              switches=sw, jump_times=jumps)
    cycles = max(int(np.count_nonzero(ok)) - 1, 0) // 2
    return Quantification(fd_op, fs_op, jump_op, cycles, multi, n_poor, None, tuple(warnings), sw,
                          jumps)
