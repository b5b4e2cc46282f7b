"""The cycle of a window: the oscillation the shape tests look at, and the signals as they
see them.

Set-point and load steps inside a window hide a limit cycle from the ACF (the straight-line
detrend leaves a step, which dominates it), so each signal is also looked at with a running
median over a third of the window removed (:func:`.oscillation.baseline`), and the variant
with the more significant ACF lobe is kept. A cycle counts when its ACF lobe is significant
and its regularity exceeds ``MIN_REGULARITY``, looser than Thornhill's 1 (which
``Assessment.oscillating`` keeps): stick-slip cycles under load are irregular, and every
shape test has its own guard against noise.
"""

from __future__ import annotations

import dataclasses

from .._validate import FloatArray
from .oscillation import Oscillation, baseline, detect_oscillations, detrend

__all__ = ["MIN_REGULARITY", "Cycle", "Signal", "find_cycle"]

MIN_REGULARITY = 0.5
BASELINE_FRACTION = 3  # running-median window: a third of the window


@dataclasses.dataclass(frozen=True)
class Signal:
    """One signal as the shape tests see it: ``x`` with its baseline (or line) removed."""

    x: FloatArray
    osc: Oscillation
    significance: float
    unstepped: FloatArray  # baseline and line removed, whichever variant ``x`` is


@dataclasses.dataclass(frozen=True)
class Cycle:
    """The oscillation of a window: ``period`` in samples from ``source`` ("OP"/"PV"),
    None when neither signal cycles. ``op``/``pv`` are the signals as the tests see them."""

    op: Signal
    pv: Signal
    period: float | None
    source: str
    regular: bool  # Thornhill's regularity > 1 on OP or PV: what ``oscillating`` reports

    @property
    def cycling(self) -> bool:
        return self.period is not None


def _unstepped(x: FloatArray) -> FloatArray:
    """``x`` without its running-median baseline and straight line."""
    if x.size < 48:
        return detrend(x)
    return detrend(x - baseline(x, x.size // BASELINE_FRACTION))


def _signals(op: FloatArray, pv: FloatArray) -> tuple[Signal, Signal]:
    """OP and PV as the shape tests see them: of each signal's variants (line removed, or
    baseline and line), the one with the more significant ACF lobe. The ACFs of all
    variants in one batch."""
    unstepped = [_unstepped(x) for x in (op, pv)]
    variants = [[detrend(x), u] if x.size >= 48 else [u]
                for x, u in zip((op, pv), unstepped, strict=True)]
    oscs = iter(detect_oscillations([y for v in variants for y in v],
                                    min_regularity=MIN_REGULARITY))
    out = []
    for ys, u in zip(variants, unstepped, strict=True):
        best: Signal | None = None
        for y in ys:
            osc = next(oscs)
            sig = osc.significance if osc.oscillating else -1.0
            if best is None or sig > best.significance:
                best = Signal(y, osc, sig, u)
        assert best is not None
        out.append(best)
    return out[0], out[1]


def find_cycle(op: FloatArray, pv: FloatArray, *, integrating: bool) -> Cycle:
    """The cycle of a window (module doc); OP's for a self-regulating loop, PV's for an
    integrating one, the other signal's when that one does not cycle."""
    so, sp = _signals(op, pv)
    regular = any(s.osc.oscillating and s.osc.regularity > 1.0 for s in (so, sp))
    order = [("PV", sp), ("OP", so)] if integrating else [("OP", so), ("PV", sp)]
    for name, s in order:
        if s.osc.oscillating and s.osc.period is not None:
            return Cycle(so, sp, s.osc.period, name, regular)
    return Cycle(so, sp, None, "", False)


MIN_CYCLES = 2.5
"""Fewer periods than this in the window: too short to size a limit cycle from."""
