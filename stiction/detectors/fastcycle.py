"""A limit cycle too fast for its shape: what OP and PV still tell.

With fewer than about eight samples a period (a fast valve cycle logged every few minutes,
as the Tennessee Eastman records at 180 s and 600 s sampling), the triangle and square
shapes the other tests look for are gone, and the cycle may alias into an irregular
alternation. Two signatures survive:

1. **A sustained limit cycle.** A cycle of steady amplitude spends its time near its two
   extremes: its values have a two-peaked distribution, excess kurtosis near -1.5 (a sine)
   to -2 (a square wave). A linear loop rung by noise (aggressive tuning) has a Gaussian
   distribution (0). Limit cycles with steady amplitude come from nonlinearities in the
   loop, a sticky valve first among them (Thornhill & Hägglund 1997; the same non-Gaussianity
   Choudhury et al. 2004 measure by the bicoherence, which needs slower cycles). Both OP
   and PV must show it (excess kurtosis at most ``BIMODAL``), and both must cross their
   median at least every fourth sample (``FAST``): a step in the window makes two levels
   too, but crosses once.
2. **Does PV follow OP?** With a valve that follows OP, a cycle this fast shows PV moving
   with OP at lag 0 (in phase or against it by the loop's sign): the OP-PV plot is a thin
   line (Choudhury et al. 2006), the cross-correlation even (Horch 1999), |corr| near 1. A
   valve that sticks moves only after OP has travelled its band: PV lags OP by a good part
   of the cycle and the lag-0 correlation falls.

Vote: +1 when both signatures hold and ``|corr| <= LAGGING``; -1 when the cycle is fast and
sustained but ``|corr| >= FOLLOWING`` (a linear cycle the valve follows); 0 otherwise
(slower cycles are for the shape tests). The thresholds are ours, set on the Tennessee
Eastman and plant records (``../shared/data``): |corr| 0.00-0.62 on the sticky IDV 14
reactor valve, 0.95 on the one fast non-sticky plant loop; that is few records, and the
calibrated weight of this vote says how far it is trusted.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.arrays import median
from .base import Window

__all__ = ["FastCycle", "detect", "fast_cycle"]

BIMODAL = -0.8
FAST = 0.25
LAGGING = 0.75
FOLLOWING = 0.9
MIN_SAMPLES = 32


@dataclasses.dataclass(frozen=True)
class FastCycle:
    """``kurtosis`` (excess, OP and PV), ``crossing`` (median crossings per sample, the
    slower of OP and PV) and ``corr`` (OP-PV correlation at lag 0)."""

    vote: int
    note: str
    kurtosis: tuple[float, float] | None = None
    crossing: float | None = None
    corr: float | None = None

    def evidence(self) -> Evidence:
        """Test ``"fast_cycle"``, value |corr| (None when the test did not run)."""
        return Evidence("fast_cycle", None if self.corr is None else abs(self.corr),
                        self.vote, self.note)


def _kurtosis(x: FloatArray) -> float:
    y = x - np.add.reduce(x) / x.size
    y2 = y * y
    v = float(np.add.reduce(y2) / y2.size)
    return float(np.add.reduce(y2 * y2) / y2.size) / (v * v) - 3.0 if v > 0 else 0.0


def _ptp(x: FloatArray) -> float:
    """``np.ptp(x)`` without its Python layers."""
    return float(np.maximum.reduce(x) - np.minimum.reduce(x))


def _crossing(x: FloatArray) -> float:
    above = x > median(x)
    return np.count_nonzero(above[1:] != above[:-1]) / (above.size - 1)


def fast_cycle(op: FloatArray, pv: FloatArray) -> FastCycle:
    """The fast-cycle test (module doc) on OP and PV with their baselines removed
    (equal-length, finite)."""
    if op.size < MIN_SAMPLES or _ptp(op) == 0 or _ptp(pv) == 0:
        return FastCycle(0, "too short or flat to tell")
    k = (_kurtosis(op), _kurtosis(pv))
    cross = min(_crossing(op), _crossing(pv))
    if cross < FAST:
        return FastCycle(0, "no cycle faster than 8 samples", k, cross)
    if max(k) > BIMODAL:
        return FastCycle(0, f"fast, but no sustained limit cycle in both OP and PV (excess "
                         f"kurtosis {k[0]:.2f}, {k[1]:.2f})", k, cross)
    corr = float(np.corrcoef(op, pv)[0, 1])
    if abs(corr) >= FOLLOWING:
        return FastCycle(-1, f"fast limit cycle with PV following OP (|corr| {abs(corr):.2f}):"
                         " the valve follows", k, cross, corr)
    if abs(corr) <= LAGGING:
        return FastCycle(1, f"fast limit cycle (OP and PV two-peaked, kurtosis {k[0]:.2f}, "
                         f"{k[1]:.2f}) with PV lagging OP (|corr| {abs(corr):.2f}): the valve "
                         "moves only after OP has travelled", k, cross, corr)
    return FastCycle(0, f"fast limit cycle, PV neither follows nor lags OP clearly "
                     f"(|corr| {abs(corr):.2f})", k, cross, corr)


def detect(w: Window) -> FastCycle:
    """``fast_cycle``: a sustained limit cycle under 8 samples a period in OP and PV (the
    signals without their steps)."""
    return fast_cycle(w.cycle.op.unstepped, w.cycle.pv.unstepped)
