"""OP of a step test split into holds and steps, or the recording refused as no step test.

A step test holds the loop in manual: OP stands still for a while (a *hold*), goes to a
new value (a *step*), stands still again. A step is any run of changes in one direction:
one sample, a historian's interpolated stamps between two holds, or an operator's ramp
over several seconds (an operator's step is rarely instant; the valve's response to it is
read from OP's path, :mod:`.response`). OP that changes in more than a quarter of the
samples, or that turns back and forth inside its runs of changes in more than a quarter of
them, is a loop in automatic (or a continuous ramp), not a step test: refused by name.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from .._errors import StictionError
from .._validate import FloatArray

__all__ = ["MIN_HOLD", "Holds", "NotAStepTest", "split_holds"]

MIN_HOLD = 5
"""Samples a hold needs to be measured (fewer: the steps on both sides count as one)."""
NEEDS = ("a step test needs the loop in manual, OP held still between steps (each hold "
         "long enough for the response to settle: dead time plus four time constants), "
         "stepped up and down with reversals (the ISA-75.25.01 sequence: small steps, "
         "then larger ones)")


class NotAStepTest(StictionError):
    """The recording is no step test; the message says why and what a step test needs."""


@dataclasses.dataclass(frozen=True)
class Holds:
    """The holds of a step test: hold ``k`` is samples ``start[k]:end[k]`` at OP
    ``level[k]``; step ``k`` (k >= 1) leads from hold ``k - 1`` to hold ``k`` and begins at
    sample ``step_at[k]`` (the first sample whose OP left hold ``k - 1``; ``step_at[0]``
    is 0) and ends at ``start[k]`` (the same sample for an instant step, later for a
    ramp); ``op`` is OP with its gaps filled, one value per sample."""

    level: FloatArray
    start: NDArray[np.intp]
    end: NDArray[np.intp]
    step_at: NDArray[np.intp]
    op: FloatArray

    def path(self, k: int) -> tuple[NDArray[np.intp], FloatArray]:
        """Step ``k`` (>= 1) as OP travelled it: the samples at which OP changed and the
        share of the step's change at each (summing to 1; one sample, share 1, for an
        instant step or one that went out and back)."""
        a, b = int(self.step_at[k]), int(self.start[k])
        if b <= a:
            return np.array([a], dtype=np.intp), np.ones(1)
        at = np.arange(a, b + 1, dtype=np.intp)
        d = self.op[at] - self.op[at - 1]
        total = float(d.sum())
        if abs(total) <= 1e-12 or np.any(d * total < 0):
            return np.array([b], dtype=np.intp), np.ones(1)
        return at, d / total

    @property
    def n(self) -> int:
        return int(self.level.size)

    @property
    def op_steps(self) -> FloatArray:
        """OP change of each step, hold 1 on (``n - 1`` values)."""
        return np.diff(self.level)


def _filled(op: FloatArray) -> FloatArray:
    """OP with gaps (NaN) carried forward (leading ones backward): a hold's missing
    samples are still that hold."""
    good = np.isfinite(op)
    if not good.any():
        raise NotAStepTest("OP holds no numbers: " + NEEDS)
    idx = np.where(good, np.arange(op.size), 0)
    np.maximum.accumulate(idx, out=idx)
    out = op[idx]
    out[: int(np.argmax(good))] = op[int(np.argmax(good))]
    return out


def _changes(op: FloatArray) -> NDArray[np.intp]:
    """Sign of each sample-to-sample change beyond the recording's resolution."""
    span = float(np.ptp(op))
    tol = max(1e-9, 1e-6 * max(span, float(np.max(np.abs(op)))))
    d = np.diff(op)
    return np.where(np.abs(d) > tol, np.sign(d), 0.0).astype(np.intp)


def split_holds(op: FloatArray) -> Holds:
    """The holds and steps of ``op`` (one sample per row, gaps as NaN); NotAStepTest,
    naming what a step test needs, for OP that never steps or that moves continuously."""
    op = _filled(np.asarray(op, dtype=np.float64))
    sign = _changes(op)
    moving = np.flatnonzero(sign)
    if moving.size == 0:
        raise NotAStepTest(f"OP never steps (it stays at {op[0]:.6g} in all {op.size} "
                           f"samples): {NEEDS}")
    share = moving.size / max(sign.size, 1)
    # runs of consecutive changes: [a, b] sample indices of the diff
    breaks = np.flatnonzero(np.diff(moving) > 1)
    run_a = np.concatenate(([moving[0]], moving[breaks + 1]))
    run_b = np.concatenate((moving[breaks], [moving[-1]]))
    # a run that turns back on itself is OP in automatic; one in one direction is a step,
    # however many samples it takes (an operator's ramp)
    turning = [(a, b) for a, b in zip(run_a, run_b, strict=True)
               if np.unique(sign[a:b + 1]).size > 1]
    if share > 0.25 or len(turning) > max(2, run_a.size // 4):
        raise NotAStepTest(f"OP changes in {moving.size} of {sign.size} samples (it moves "
                           "continuously, as in automatic or a continuous ramp, not in "
                           f"steps): {NEEDS}")
    # holds between the runs; a hold shorter than MIN_HOLD joins the runs around it
    starts = np.concatenate(([0], run_b + 1))
    ends = np.concatenate((run_a + 1, [op.size]))  # exclusive: run_a + 1 left the hold
    keep = (ends - starts) >= MIN_HOLD
    keep[0] = keep[0] or starts.size == 1
    if keep.sum() < 2:
        raise NotAStepTest(f"OP has no two holds of at least {MIN_HOLD} samples: {NEEDS}")
    ks = np.flatnonzero(keep)
    start, end = starts[ks], ends[ks]
    level = np.array([float(np.median(op[a:b])) for a, b in zip(start, end, strict=True)])
    step_at = np.concatenate(([0], end[:-1])).astype(np.intp)
    return Holds(level, start.astype(np.intp), end.astype(np.intp), step_at, op)
