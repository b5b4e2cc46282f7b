"""A stretch to analyse: where a long window cycles only in bursts, the stretch that cycles.

A sticky valve that cycles for an hour, rests for two and cycles again leaves a long export
whose ACF is irregular (a regularity of 0.2-0.4 where one clean burst reads 3 or more): the
whole window then reads ``not_oscillating`` or ``undetermined`` although one burst, analysed
alone, shows the cycle plainly (issue 32). :func:`regular_stretch` looks for it: sub-windows
of a sixteenth, an eighth and a quarter of the window (at least ``JUDGE_SAMPLES``), a half
sub-window apart, each signal's oscillation by Thornhill's test
(:func:`stiction.signal.oscillation.detect_oscillations`); of the sub-windows where OP or PV
cycles regularly (regularity above 1, a significant ACF lobe, at least ``MIN_CYCLES`` cycles),
the one with the highest ACF lobe one period out (the cleanest cycle; a longer sub-window
only where its lobe beats a shorter one's by ``1 / CLOSE``) names the length, and the run of
such sub-windows of that length around it is the stretch.
:func:`stiction.analyze` says it in the reason of a window whose own cycle is not regular;
``stiction analyze`` prints it in the file's time with the ``--from``/``--to`` to pass back.
"""

from __future__ import annotations

import dataclasses
import math

from .._validate import FloatArray
from ..signal.oscillation import detect_oscillations, detrend
from .enough import JUDGE_SAMPLES, duration

__all__ = ["FRACTIONS", "Stretch", "regular_stretch"]

FRACTIONS = (16, 8, 4)
"""Sub-window lengths tried, as fractions 1/k of the window."""
REGULAR = 1.0
"""Thornhill's regularity a sub-window's cycle must exceed."""
MIN_CYCLES = 4
CLOSE = 0.8
"""A longer sub-window is preferred only where its cycle is cleaner than this share of the
shorter one's (its ACF lobe): the tightest stretch that shows the cycle."""
"""Cycles a sub-window must hold (a slow wander's two or three crossings are no cycle)."""


@dataclasses.dataclass(frozen=True)
class Stretch:
    """Samples ``start`` to ``stop`` (exclusive) of the window, where ``source`` ("OP" or
    "PV") cycles every ``period`` samples with ``regularity`` (its best sub-window's)."""

    start: int
    stop: int
    period: float
    regularity: float
    source: str
    lobe: float = 0.0  # the ACF one period out in its best sub-window (how clean the cycle is)

    def reason(self, ts: float) -> str:
        """One sentence, times from the window's start (``ts``: seconds per sample)."""
        return (f" The cycling comes in bursts: {self.source} cycles regularly every "
                f"{duration(self.period * ts)} (regularity {min(self.regularity, 99.0):.1f}) "
                f"from {duration(self.start * ts)} to {duration(self.stop * ts)} into the "
                "window: analyse that stretch alone.")


def regular_stretch(op: FloatArray, pv: FloatArray) -> Stretch | None:
    """The stretch of a window (equal-length finite ``op``, ``pv``) that cycles regularly
    (module doc), or None when no sub-window does."""
    n = op.size
    best: tuple[Stretch, int, list[Stretch | None]] | None = None  # its sub-window's index
    for k in FRACTIONS:  # the shortest sub-windows first: the tightest stretch
        length = n // k
        if length < JUDGE_SAMPLES:
            continue
        found = [_cycles(op, pv, s, s + length) for s in range(0, n - length + 1, length // 2)]
        for i, f in enumerate(found):
            if f is not None and (best is None or f.lobe > best[0].lobe / CLOSE):
                best = (f, i, found)
    if best is None:
        return None
    top, i, found = best
    lo, hi = i, i
    while lo > 0 and found[lo - 1] is not None:
        lo -= 1
    while hi + 1 < len(found) and found[hi + 1] is not None:
        hi += 1
    first, last = found[lo], found[hi]
    assert first is not None
    assert last is not None
    return dataclasses.replace(top, start=first.start, stop=last.stop)


def _cycles(op: FloatArray, pv: FloatArray, start: int, stop: int) -> Stretch | None:
    """The more regular of OP's and PV's cycles in samples ``start:stop``, where one
    cycles regularly, else None."""
    out = None
    oscs = detect_oscillations([detrend(op[start:stop]), detrend(pv[start:stop])])
    for name, osc in zip(("OP", "PV"), oscs, strict=True):
        lobe = osc.significance / math.sqrt(stop - start)
        if osc.oscillating and osc.period is not None and osc.regularity > REGULAR and \
                (stop - start) >= MIN_CYCLES * osc.period and (out is None or lobe > out.lobe):
            out = Stretch(start, stop, osc.period, osc.regularity, name, lobe)
    return out
