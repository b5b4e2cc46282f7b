"""Valve not responding: OP travels, PV stands still although its transmitter is alive.

A valve stuck so hard that the controller's whole travel does not break it away (or a closed
block valve, a blocked line) leaves PV at one value while integral action ramps OP on. Plant
record 2411FIC10104 (``../shared/data/plant-stictiongpt``) is the pattern: the flow falls
to 0 and stays there for 441 samples while OP ramps from 5 % to 78 %. That is not a data
problem to hide in ``bad_data``; it names the valve (or the line).

The test, on one window:

1. **PV still.** The longest stretch in which consecutive PV samples differ by at most
   ``STILL_TOLERANCE`` of PV's range over the window (exact repeats, and the 1e-17 dust a
   transmitter at its low-flow cut-off reports) covers at least ``MIN_STILL_FRACTION`` of the
   window.
2. **PV alive.** PV moved elsewhere in the window (its range is not zero). A PV that never
   moved is a dead or frozen tag, which :mod:`.quality` reports as ``bad_data``.
3. **OP travelled.** Over the still stretch OP moved monotonically (net change of its
   ``M``-sample means at least ``MONOTONE`` of their total variation) by at least
   ``OP_NOISE`` OP noise SDs (second-difference estimate) and, when the OP span is known, by
   at least ``MIN_SPAN_TRAVEL`` of it. Without a span the size is reported in OP units.

A frozen transmitter (stuck at its last value while the loop runs on) shows the same
pattern; the reason says so. Thresholds are dimensionless: no OP or PV unit is assumed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray
from ..signal.noise import noise_sd

__all__ = ["NotResponding", "not_responding"]

STILL_TOLERANCE = 1e-9
MIN_STILL_FRACTION = 0.3
MONOTONE = 0.8
OP_NOISE = 20.0
MIN_SPAN_TRAVEL = 0.05
M = 10


@dataclasses.dataclass(frozen=True)
class NotResponding:
    """PV stood still at ``pv_value`` for ``length`` samples from ``start`` while OP
    travelled ``op_travel`` (OP units; ``span_travel`` as a fraction of span when known)."""

    start: int
    length: int
    pv_value: float
    op_travel: float
    span_travel: float | None

    def reason(self, n: int) -> str:
        size = (f"{self.span_travel:.0%} of its span" if self.span_travel is not None
                else f"{self.op_travel:+.4g} (OP units; give op_range for % of span)")
        return (f"valve not responding: OP travelled {size} while PV stood still at "
                f"{self.pv_value:.4g} for {self.length} samples ({self.length / n:.0%} of the "
                "window) though it moved before: valve stuck or closed, line blocked, or the "
                "PV transmitter frozen or at its cut-off")


def _longest_still(pv: FloatArray, tol: float) -> tuple[int, int]:
    still = np.abs(np.diff(pv)) <= tol
    if not still.any():
        return 0, 1
    m = np.concatenate(([False], still, [False])).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    k = int((ends - starts).argmax())
    return int(starts[k]), int(ends[k] - starts[k]) + 1


def not_responding(op: FloatArray, pv: FloatArray, *, span: float | None = None
                   ) -> NotResponding | None:
    """The stretch where OP travelled and PV stood still (module doc), or None.
    ``op``, ``pv``: equal-length finite 1-D arrays; ``span``: OP units of 100 % valve span."""
    n = pv.size
    rng = float(np.ptp(pv)) if n else 0.0
    if n < 3 * M or rng == 0.0 or not np.isfinite(rng):
        return None
    start, length = _longest_still(pv, STILL_TOLERANCE * rng)
    if length < MIN_STILL_FRACTION * n:
        return None
    seg = op[start : start + length]
    means = seg[: (seg.size // M) * M].reshape(-1, M).mean(axis=1)
    if means.size < 2:
        return None
    travel = float(means[-1] - means[0])
    variation = float(np.abs(np.diff(means)).sum())
    sd = noise_sd(seg)
    if variation == 0.0 or abs(travel) < MONOTONE * variation or abs(travel) <= OP_NOISE * sd:
        return None
    span_travel = None if span is None else abs(travel) / span
    if span_travel is not None and span_travel < MIN_SPAN_TRAVEL:
        return None
    return NotResponding(start, length, float(np.median(pv[start : start + length])), travel,
                         span_travel)
