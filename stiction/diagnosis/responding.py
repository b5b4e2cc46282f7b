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
pattern; the reason says so.

**A live PV** (:func:`held_while_op_ran`; issue 32: a valve stuck while OP ramps 55 -> 50 %
and the flow shows only its noise was ``not_oscillating, confidence 0.05``) is the same
finding with step 1 read within the transmitter's noise: the longest stretch in which PV's
means over ``M`` samples stay within ``HELD_NOISE`` white-noise SDs (``noise_sd``, second
differences) of each other covers ``MIN_STILL_FRACTION`` of the window, PV is alive (its
noise is not zero), and over the stretch OP ran one way (net change of its means at least
``MONOTONE`` of their range) by at least ``OP_NOISE`` OP noise SDs and, when the span is
known, ``MIN_SPAN_TRAVEL`` of it, along a straight line (its means within ``RAMP_LINE`` of
the travel from their fitted line: the integral action driving OP on against a constant
error; not OP's quick move and rest taking up a load step, as in the TEP reactor loop under
IDV 4 or 6, nor OP wandering after a drifting load, as in a realistic "noise" loop whose OP
strays 0.19 of its travel from the line; a sticky valve's stretches stray 0.01-0.09).
From OP and PV alone this cannot be told from a load ramp that OP follows exactly while PV
rests at its set point (the reason says so): a valve that moved with OP would have moved
PV unless something else cancelled it. It is not a gate: it answers only
where the analysis found the loop calm (``not_oscillating``); a window whose stick-slip the
tests saw keeps their verdict. Measured: no window of ``bench false_alarms`` (good valves
under random loads) meets it, nor a TEP run, nor a realistic simulation without a sticky
valve; of the plant records, sticky ones only.

Thresholds are dimensionless: no OP or PV unit is assumed.
"""

from __future__ import annotations

import collections
import dataclasses

import numpy as np

from .._validate import FloatArray
from ..signal.noise import noise_sd

__all__ = ["NotResponding", "held_while_op_ran", "not_responding"]

STILL_TOLERANCE = 1e-9
MIN_STILL_FRACTION = 0.3
MONOTONE = 0.8
OP_NOISE = 20.0
MIN_SPAN_TRAVEL = 0.05
M = 10
HELD_NOISE = 3.0
RAMP_LINE = 0.1


@dataclasses.dataclass(frozen=True)
class NotResponding:
    """PV stood still at ``pv_value`` for ``length`` samples from ``start`` while OP
    travelled ``op_travel`` (OP units; ``span_travel`` as a fraction of span when known)."""

    start: int
    length: int
    pv_value: float
    op_travel: float
    span_travel: float | None
    pv_noise: float = 0.0  # PV's noise SD where it held within its noise (a live PV)

    def reason(self, n: int) -> str:
        size = (f"{self.span_travel:.0%} of its span" if self.span_travel is not None
                else f"{self.op_travel:+.4g} (OP units; give op_range for % of span)")
        where = f"{self.length} samples ({self.length / n:.0%} of the window)"
        if self.pv_noise > 0:
            return (f"valve not responding: OP travelled {size} while PV held within its "
                    f"noise (SD {self.pv_noise:.3g}) at {self.pv_value:.4g} for {where}: "
                    "valve stuck or closed, or line blocked; or a load that OP followed "
                    "exactly while PV rested at its set point")
        return (f"valve not responding: OP travelled {size} while PV stood still at "
                f"{self.pv_value:.4g} for {where} though it moved before: valve stuck or "
                "closed, line blocked, or the PV transmitter frozen or at its cut-off")


def _longest_still(pv: FloatArray, tol: float) -> tuple[int, int]:
    still = np.abs(np.diff(pv)) <= tol
    if not still.any():
        return 0, 1
    m = np.concatenate(([False], still, [False])).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    k = int((ends - starts).argmax())
    return int(starts[k]), int(ends[k] - starts[k]) + 1


def _longest_held(pv: FloatArray, band: float) -> tuple[int, int]:
    """Start and length (samples, whole blocks of ``M``) of the longest run of PV's
    ``M``-sample means whose range stays within ``band`` (two pointers, the run's minimum
    and maximum in monotone queues: one pass)."""
    means = pv[: (pv.size // M) * M].reshape(-1, M).mean(axis=1).tolist()
    lows: collections.deque[int] = collections.deque()
    highs: collections.deque[int] = collections.deque()
    best, lo = (0, 0), 0
    for hi, x in enumerate(means):
        while lows and means[lows[-1]] >= x:
            lows.pop()
        lows.append(hi)
        while highs and means[highs[-1]] <= x:
            highs.pop()
        highs.append(hi)
        while means[highs[0]] - means[lows[0]] > band:
            lo += 1
            if lows[0] < lo:
                lows.popleft()
            if highs[0] < lo:
                highs.popleft()
        if hi + 1 - lo > best[1]:
            best = (lo, hi + 1 - lo)
    return best[0] * M, best[1] * M


def _op_ran(op: FloatArray, span: float | None, *, monotone_of: str) -> float | None:
    """OP's one-way travel over a stretch (module doc, step 3), or None. ``monotone_of``:
    "variation" (the still PV's rule) or "range" (the live PV's, robust to OP's noise)."""
    means = op[: (op.size // M) * M].reshape(-1, M).mean(axis=1)
    if means.size < 2:
        return None
    travel = float(means[-1] - means[0])
    spread = (float(np.abs(np.diff(means)).sum()) if monotone_of == "variation"
              else float(np.ptp(means)))
    if spread == 0.0 or abs(travel) < MONOTONE * spread or abs(travel) <= OP_NOISE * noise_sd(op):
        return None
    if span is not None and abs(travel) / span < MIN_SPAN_TRAVEL:
        return None
    return travel


def not_responding(op: FloatArray, pv: FloatArray, *, span: float | None = None
                   ) -> NotResponding | None:
    """The stretch where OP travelled and PV stood still (module doc), or None. ``op``,
    ``pv``: equal-length finite 1-D arrays; ``span``: OP units of 100 % valve span."""
    n = pv.size
    rng = float(np.ptp(pv)) if n else 0.0
    if n < 3 * M or rng == 0.0 or not np.isfinite(rng):
        return None
    start, length = _longest_still(pv, STILL_TOLERANCE * rng)
    if length < MIN_STILL_FRACTION * n:
        return None
    travel = _op_ran(op[start : start + length], span, monotone_of="variation")
    if travel is None:
        return None
    return NotResponding(start, length, float(np.median(pv[start : start + length])),
                         travel, None if span is None else abs(travel) / span)


def held_while_op_ran(op: FloatArray, pv: FloatArray, *, span: float | None = None
                      ) -> NotResponding | None:
    """The stretch where OP ran on, steadily, while a live PV held within its noise
    (module doc, "a live PV"), or None. Arguments as :func:`not_responding`."""
    sd = noise_sd(pv)
    if pv.size < 3 * M or sd == 0.0 or not np.isfinite(sd):
        return None
    start, length = _longest_held(pv, HELD_NOISE * sd)
    if length < MIN_STILL_FRACTION * pv.size:
        return None
    seg = op[start : start + length]
    travel = _op_ran(seg, span, monotone_of="range")
    if travel is None or not _steady(seg):
        return None
    return NotResponding(start, length, float(np.median(pv[start : start + length])), travel,
                         None if span is None else abs(travel) / span, sd)


def _steady(op: FloatArray) -> bool:
    """OP ramped along a straight line (its ``M``-sample means within ``RAMP_LINE`` of its
    travel from their least-squares line), as integral action drives it against a constant
    error: not the quick move and rest of OP taking up a load step, nor the wander of OP
    following a drifting load."""
    means = op[: (op.size // M) * M].reshape(-1, M).mean(axis=1)
    if means.size < 4:
        return False
    x = np.arange(means.size, dtype=np.float64)
    line = np.polyval(np.polyfit(x, means, 1), x)
    travel = float(abs(line[-1] - line[0]))
    return travel > 0 and float(np.abs(means - line).max()) <= RAMP_LINE * travel
