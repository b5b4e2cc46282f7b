"""Stiction size from OP and PV (He & Wang 2014, section 3.1), plus the multi-jump check.

All of it rests on the limit cycle of a sticky valve that jumps once per half cycle: VP is a
rectangular wave of height J = K (fs - fd) (eq 7), switching at the PV onsets found by
:mod:`stiction._switching`, each delayed by the dead time ``delay`` after the jump.

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
jump and is at least a quarter of a typical jump; or when its fit residual RMS exceeds both
three times the PV noise SD and 5 % of the PV swing; or when two consecutive jumps go the
same way (a missed switch). More than a quarter of flagged half cycles sets ``multi_jump``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from ._detect import noise_sd
from ._segments import closed_rss
from ._switching import Switches, find_switches
from ._validate import FloatArray

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
    reason: str | None = None
    warnings: tuple[str, ...] = ()
    switches: Switches | None = None
    jump_times: FloatArray | None = None  # sample positions of the valve jumps


def _mean(x: FloatArray) -> float:
    return float(stats.trim_mean(x, TRIM)) if x.size >= 5 else float(np.mean(x))


def _overshoot(op: FloatArray, jumps: FloatArray) -> float:
    """Mean excess of the net force over fs at the jumps: the valve only moves at sample
    instants, so a ramping OP passes fs by half an OP step per sample on average."""
    n = np.clip(np.round(jumps).astype(np.intp), 5, op.size - 1)
    win = n[:, None] + np.arange(-5, 1)[None, :]
    seg = op[win]
    t = np.arange(-5, 1) + 2.5
    slope = (seg - seg.mean(axis=1, keepdims=True)) @ t / float(t @ t)
    return 0.5 * float(np.mean(np.abs(slope)))


def _second_step(
    y: FloatArray, i: int, j: int, tau: float | None, *, margin: int
) -> float | None:
    """Is there a second valve jump inside the half cycle ``y[i:j]``?

    Compares the one-curve fit with the best two-curve fit (same tau, split anywhere at
    least ``margin`` samples from the ends): when the split is significant (F > F_SPLIT)
    returns the change of the steady state (self-regulating) or slope (integrating) at the
    split, else None. Sums over the left pieces are prefix sums and over the right pieces
    suffix sums, so neither suffers cancellation; the basis is referenced to the middle of
    the half cycle (a scale factor, which the 2-parameter fit does not see).
    """
    n = j - i
    if n < 2 * margin + 8:
        return None
    t = np.arange(n, dtype=np.float64) - n / 2.0
    g = t if tau is None else np.exp(np.clip(-t / tau, -300.0, 300.0))
    yy = y[i:j] - float(np.mean(y[i:j]))
    cols = np.stack((np.ones(n), g, g * g, yy, yy * g, yy * yy))
    pre = np.cumsum(cols, axis=1)  # sums over [0, c]
    suf = np.cumsum(cols[:, ::-1], axis=1)[:, ::-1]  # sums over [c, n)
    c = np.arange(margin, n - margin)
    left = pre[:, c - 1]
    right = suf[:, c]
    r_left, a_left, b_left = closed_rss(left)
    r_right, a_right, b_right = closed_rss(right)
    r_one, _, _ = closed_rss(pre[:, -1:])
    two = r_left + r_right
    k = int(np.argmin(two))
    rss2 = float(two[k])
    f = (float(r_one[0]) - rss2) / 2.0 / max(rss2 / (n - 4), 1e-300)
    if f < F_SPLIT:
        return None
    if tau is None:
        return float(b_right[k] - b_left[k])
    return float(a_right[k] - a_left[k])


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
) -> Quantification:
    """Estimate fd, fs (OP units) from a window already judged sticky."""
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
    swing = _mean(np.abs(np.diff(u)))

    # jump sizes between consecutive half cycles, PV units (per sample for integrators)
    lev = sw.b if integrating else sw.a
    dj = np.diff(lev)
    warnings: list[str] = []

    # multi-jump check
    sigma = noise_sd(pv)
    swing_pv = float(np.percentile(pv, 95) - np.percentile(pv, 5))
    rms = np.sqrt(sw.rss / np.maximum(sw.count, 1.0))
    bad_fit = rms > np.maximum(RESID_NOISE_FACTOR * sigma, RESID_SWING_FRACTION * swing_pv)
    if dj.size:
        typical = float(np.median(np.abs(dj)))
        for s_idx in range(sw.a.size):
            i = int(np.floor(sw.onsets[s_idx])) + 1
            j = int(np.floor(sw.onsets[s_idx + 1])) + 1
            step = _second_step(pv, i, j, sw.tau, margin=max(5, int(0.02 * period)))
            main = dj[s_idx - 1] if s_idx >= 1 else (dj[0] * -1.0)
            if step is not None and np.sign(step) == np.sign(main) \
                    and abs(step) >= SECOND_STEP_FRACTION * typical:
                bad_fit[s_idx] = True
    same_dir = np.zeros(sw.a.size, dtype=bool)
    if dj.size >= 2:
        same = np.sign(dj[1:]) == np.sign(dj[:-1])
        same_dir[1:-1] |= same
    flagged = bad_fit | same_dir
    multi = bool(flagged.mean() > MULTI_JUMP_FRACTION) if flagged.size else False
    if flagged.any():
        warnings.append(f"{int(flagged.sum())} of {flagged.size} half cycles do not fit a "
                        "single valve jump")

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
    cycles = max(int(np.count_nonzero(ok)) - 1, 0) // 2
    return Quantification(fd_op, fs_op, jump_op, cycles, multi, None, tuple(warnings), sw,
                          jumps)
