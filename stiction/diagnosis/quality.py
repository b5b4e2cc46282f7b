"""Data-quality gates: is a window of OP/PV fit for analysis?

Each gate either passes (possibly with a warning) or returns the reason the window is
``bad_data``. Gaps: non-finite samples (NaN, +-inf, e.g. the gateway's missed polls) are
**interpolated linearly** when they are few and short - at most ``MAX_MISSING_FRACTION`` of
the window in total and no run longer than ``max(MIN_GAP_LIMIT, n * MAX_GAP_FRACTION)``
samples; leading and trailing gaps are trimmed instead. A window with more or longer gaps is
judged ``bad_data`` ("too gappy"): interpolating across a longer gap would invent a ramp
that the stiction detector reads as a triangle.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray
from ..signal.arrays import median, percentiles
from ..signal.noise import noise_sd
from .responding import NotResponding, not_responding

__all__ = ["MIN_SAMPLES", "Cleaned", "check_quality"]

MIN_SAMPLES = 32
"""Fewer samples than this cannot hold the several cycles the method needs."""
MAX_MISSING_FRACTION = 0.10
MAX_GAP_FRACTION = 0.02
MIN_GAP_LIMIT = 5
SATURATION_BAND = 0.002  # fraction of OP's own range counted as "at its extreme"
SATURATION_RUN = 3  # samples: a pinned OP stays at its extreme, a turning one passes it
MAX_SATURATED_FRACTION = 0.20
MAX_FROZEN_FRACTION = 0.50  # longest run of identical values, fraction of the window
OP_MOVED_FRACTION = 0.05  # OP travel (of its range) during a frozen PV worth pointing out
MIN_LEVELS = 10  # distinct PV levels over its range below which PV is "quantised"
WARN_LEVELS = 40


@dataclasses.dataclass(frozen=True)
class Cleaned:
    """The outcome of the gates: ``reason`` is None when the window passed."""

    op: FloatArray
    pv: FloatArray
    reason: str | None
    warnings: tuple[str, ...] = ()
    start: int = 0  # index of op[0] in the caller's window (leading gap trimmed)
    not_responding: NotResponding | None = None  # OP travelled, PV still (see ._responding)


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start indices and lengths of the runs of True in a boolean array."""
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    d = np.diff(m)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    return starts, ends - starts


def _longest_constant_run(x: FloatArray) -> tuple[int, int]:
    """Start and length of the longest run of identical consecutive samples."""
    same = np.diff(x) == 0
    if not same.any():
        return 0, 1
    starts, lengths = _runs(same)
    k = int(lengths.argmax())
    return int(starts[k]), int(lengths[k]) + 1


def _op_moved(op: FloatArray, start: int, run: int, span: float | None) -> str:
    """The hint when PV stood still while OP travelled: a PV frozen while the controller
    drives the valve over ``OP_MOVED_FRACTION`` of its span (or, span unknown, over 20 of
    its noise SDs) is not just a dead tag."""
    seg = op[start : start + run]
    travel = float(np.ptp(seg))
    if span is not None:
        if travel < OP_MOVED_FRACTION * span:
            return ""
        size = f"{100.0 * travel / span:.0f} % of its range"
    else:
        if travel <= 20.0 * noise_sd(seg):
            return ""
        size = f"{travel:.4g} (OP units)"
    return (f" while OP moved {size}: valve stuck or not responding, line blocked, or the "
            "PV transmitter dead or at its cut-off")


def _levels(x: FloatArray) -> float:
    """How many resolution steps the signal's range spans (inf for unquantised data)."""
    steps = np.abs(np.diff(x))
    steps = steps[steps > 0]
    if steps.size == 0:
        return 0.0
    span = float(np.ptp(x))
    # the quantum: a low percentile of the non-zero steps, robust to a few odd samples
    q = percentiles(steps, (5.0,))[0]
    # unquantised data has steps of every size; only call it a quantum if steps are
    # (nearly) multiples of it
    ratio = steps / q
    if median(np.abs(ratio - np.round(ratio))) > 0.05:
        return float("inf")
    return span / q


def _saturation(op: FloatArray) -> tuple[float, str, float] | None:
    """Share of the window OP spends pinned at its own minimum or maximum (runs of at least
    ``SATURATION_RUN`` samples within ``SATURATION_BAND`` of its range), which extreme holds
    most of it, and its value. No OP range is assumed: a controller output clamped at 0 %,
    at 4 mA or at a raw count of 16383 is pinned at its own extreme in every unit."""
    lo, hi = float(op.min()), float(op.max())
    band = SATURATION_BAND * (hi - lo)
    best: tuple[float, str, float] | None = None
    for name, mask, value in (("minimum", op <= lo + band, lo), ("maximum", op >= hi - band, hi)):
        _, lengths = _runs(mask)
        pinned = int(lengths[lengths >= SATURATION_RUN].sum())
        if best is None or pinned / op.size > best[0]:
            best = (pinned / op.size, name, value)
    return best


def _fill_gaps(x: FloatArray, bad: np.ndarray) -> FloatArray:
    idx = np.arange(x.size)
    return np.interp(idx, idx[~bad], x[~bad]) if bad.any() else x


def check_quality(op: FloatArray, pv: FloatArray, span: float | None = None) -> Cleaned:
    """Run every gate on ``op``, ``pv`` (equal-length 1-D float arrays); ``span``: OP units
    of 100 % valve span, when known (only to size the OP travel in a reason)."""
    n = op.size
    warnings: list[str] = []

    def bad(reason: str) -> Cleaned:
        return Cleaned(op, pv, reason, tuple(warnings))

    if n < MIN_SAMPLES:
        return bad(f"window too short: {n} samples, need at least {MIN_SAMPLES}")

    # -- gaps
    missing = ~(np.isfinite(op) & np.isfinite(pv))
    n_missing = int(missing.sum())
    start = 0
    if n_missing:
        if n_missing == n:
            return bad("no finite samples in the window")
        good = np.flatnonzero(~missing)
        start, stop = int(good[0]), int(good[-1]) + 1
        trimmed = start + (n - stop)
        op, pv, missing = op[start:stop], pv[start:stop], missing[start:stop]
        if n_missing / n > MAX_MISSING_FRACTION:
            return bad(f"too gappy: {n_missing} of {n} samples missing "
                       f"(limit {MAX_MISSING_FRACTION:.0%})")
        _, lengths = _runs(missing)
        limit = max(MIN_GAP_LIMIT, int(n * MAX_GAP_FRACTION))
        if lengths.size and int(lengths.max()) > limit:
            return bad(f"too gappy: a gap of {int(lengths.max())} samples "
                       f"(limit {limit} samples)")
        interpolated = int(missing.sum())
        op = _fill_gaps(op, missing)
        pv = _fill_gaps(pv, missing)
        parts = []
        if interpolated:
            parts.append(f"interpolated {interpolated} missing samples")
        if trimmed:
            parts.append(f"trimmed {trimmed} missing samples at the ends")
        warnings.append("; ".join(parts))
        if op.size < MIN_SAMPLES:
            return bad(f"window too short: {op.size} finite samples, need at least "
                       f"{MIN_SAMPLES}")

    # -- OP travelled while PV stood still, though PV moved before: not a data problem
    nr = not_responding(op, pv, span=span)
    if nr is not None:
        return Cleaned(op, pv, None, tuple(warnings), start, nr)

    # -- flat or frozen
    for name, x in (("OP", op), ("PV", pv)):
        if float(np.ptp(x)) <= 1e-12 * float(np.abs(x).max()):
            if name == "PV" and (hint := _op_moved(op, 0, op.size, span)):
                return bad(f"PV is constant{hint}")
            return bad(f"{name} is constant (flat signal: loop in manual or tag frozen?)")
        at, run = _longest_constant_run(x)
        if run > MAX_FROZEN_FRACTION * x.size:
            hint = _op_moved(op, at, run, span) if name == "PV" else ""
            return bad(f"{name} frozen: {run} consecutive identical samples "
                       f"({run / x.size:.0%} of the window){hint}")

    # -- saturated OP: pinned flat at its own minimum or maximum (no unit assumed)
    sat = _saturation(op)
    if sat is not None and sat[0] > MAX_SATURATED_FRACTION:
        return bad(f"OP saturated: pinned at its {sat[1]} ({sat[2]:.6g}) for {sat[0]:.0%} of "
                   "the window")
    if sat is not None and sat[0] > 0.02:
        warnings.append(f"OP pinned at its {sat[1]} for {sat[0]:.0%} of the window")

    # -- quantised PV
    levels = _levels(pv)
    if levels < MIN_LEVELS:
        return bad(f"PV quantised: its range spans only {levels:.0f} resolution steps "
                   f"(need {MIN_LEVELS})")
    if levels < WARN_LEVELS:
        warnings.append(f"PV coarsely quantised ({levels:.0f} steps over its range)")

    return Cleaned(op, pv, None, tuple(warnings), start)
