"""Enough to judge: does a window hold enough of its loop for a verdict? (a gate)

A verdict on a loop rests on cycles, not on samples: a window of 2,000 samples of a loop that
cycles every 3,000 s (at 1 s) shows two thirds of one cycle, and a window of 40 samples of a
settled loop shows noise that the tests' statistics cannot yet tell from a pattern (good
valves cut into windows of 33-45 samples were called ``stiction`` in 1.4-2.8 % of them, issue
31). :func:`too_short` says when a window is too short, and why, by three rules:

1. **Samples.** At least ``JUDGE_SAMPLES`` (64): eight cycles of the fastest oscillation the
   shape tests read (:data:`~stiction.signal.oscillation.MIN_PERIOD`, 8 samples). Below it
   the decision's numbers (the shape of OP's and PV's distributions, the OP-PV pattern, the
   stuck intervals) are mostly noise: measured on the good valves of the three non-sticky
   scenarios (noise 0.02 and 0.2, three seeds), 46 of 2,160 windows of 33-45 samples were
   called ``stiction``, 1 of 2,142 of 60 samples.
2. **Cycles of the loop's period**, where one is known: ``SEE_CYCLES`` (2.6) of them, what
   the ACF needs to see a cycle at all (its four zero crossings within 2/3 of the window:
   7/4 periods <= 2n/3, :mod:`stiction.signal.oscillation`). :func:`stiction.analyze` does
   not ask it of the window's own cycle (the ACF's test passed it, and its mean period can
   read a little over n/2.6); the gateway asks it of a filling window's cycle, which costs
   at most a round of waiting.
3. **The loop's own time scale**, estimated from the window where no cycle was found
   (:func:`movement_scales`): 4 x the lag at which the ACF of OP (and of PV), each without
   its straight line, first crosses zero (a cycle's ACF first crosses zero a quarter period
   out, so for a window of a sine this is its period; for a window holding a part of one
   slow movement it is about the window's length, 1.1-1.3 times over). The rule depends on
   whether more samples are coming:

   - *waiting* (the gateway's window is still filling): the window must hold ``SEE_CYCLES``
     of the slower signal's scale, enough to see a cycle as slow as what it shows; waiting
     costs only time, and the full window is judged whatever it holds;
   - *final* (a file is all there is): fewer than ``PART_OF`` (1.3) of the scale of both
     signals means the window holds about one of their movements or less, a part of
     something slower: it cannot say the loop does not oscillate. Only that claim is
     withdrawn (:meth:`TooShort.withdraws`): a verdict that rests on other evidence (stick-slip
     episodes, stuck intervals) stands, and long plant records, whose OP and PV drift on every
     time scale, keep their verdicts (1 of 34 ``not_oscillating`` records of
     ``../shared/data/plant-stictiongpt`` is under 1.3, none of 36 TEP runs).

:func:`stiction.analyze` runs it after the cycle is found (a window too short gets the
verdict ``bad_data`` with this reason: the data cannot answer; the gates' ``bad_data`` says
the same of unusable data); the gateway runs it on its window while it fills
(``gateway/core/jobs.py``: ``warming_up`` until it passes).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._assessment import Verdict
from .._validate import FloatArray

__all__ = [
    "JUDGEMENTS",
    "JUDGE_SAMPLES",
    "PART_OF",
    "SEE_CYCLES",
    "TOO_SHORT",
    "TooShort",
    "duration",
    "movement_scales",
    "too_short",
]

SEE_CYCLES = 2.6
"""Cycles of an oscillation a window must hold for the ACF to see it."""
JUDGE_SAMPLES = 64
"""Samples a window needs before any verdict: eight cycles of the fastest one the tests read
(8 x :data:`~stiction.signal.oscillation.MIN_PERIOD`)."""
PART_OF = 1.3
"""A final window holding fewer of its own time scales than this shows a part of something
slower."""
TOO_SHORT = "window too short"
"""How every reason of this gate begins (and the quality gate's for fewer than 32 samples):
a caller that waits for more samples (the gateway) recognises them by it."""
JUDGEMENTS = frozenset({Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                        Verdict.NOT_OSCILLATING})
"""The verdicts that judge the loop from its window (the gates' ``bad_data`` and
``valve_not_responding`` are findings about the data or the valve, whatever its length)."""


@dataclasses.dataclass(frozen=True)
class TooShort:
    """Why a window of ``samples`` is too short: ``basis`` is ``"samples"`` (rule 1),
    ``"cycles"`` (rule 2, ``scale`` the period) or ``"movement"`` (rule 3, ``scale`` the
    time scale); ``need`` the samples it would take (the larger of the rules' needs);
    ``waiting``: more samples are coming (see the module doc). Sizes in samples."""

    samples: int
    need: int
    basis: str
    scale: float | None
    waiting: bool

    def withdraws(self, verdict: Verdict | str) -> bool:
        """Whether this shortfall withdraws ``verdict``: every judgement of the loop
        (:data:`JUDGEMENTS`), except that a final window short of its own movement only
        cannot say it does not oscillate."""
        if verdict not in JUDGEMENTS:
            return False
        return self.waiting or self.basis != "movement" or verdict == Verdict.NOT_OSCILLATING

    def reason(self, ts: float) -> str:
        """One sentence in the loop's time (``ts``: seconds per sample), ending with what
        would be enough."""
        has = f"{duration(self.samples * ts)} ({self.samples} samples)"
        need = f"{duration(self.need * ts)} ({self.need} samples)"
        if self.basis == "samples":
            head = (f"{TOO_SHORT} to judge: {has}, a verdict needs at least "
                    f"{JUDGE_SAMPLES} samples")
        elif self.basis == "cycles":
            assert self.scale is not None
            head = (f"{TOO_SHORT} for this loop's cycle of {duration(self.scale * ts)}: "
                    f"{has} hold {self.samples / self.scale:.1f} cycles, a verdict needs "
                    f"{SEE_CYCLES:g}")
        else:
            assert self.scale is not None
            head = (f"{TOO_SHORT} for this loop's speed: OP and PV move on a time scale "
                    f"of about {duration(self.scale * ts)} and {has} hold "
                    f"{self.samples / self.scale:.1f} of it, too little to tell a slow cycle "
                    "from calm")
        return f"{head}; enough: {need}"


def movement_scales(op: FloatArray, pv: FloatArray) -> tuple[float, float]:
    """The time scales OP and PV move on, in samples (rule 3 of the module doc): 4 x the
    lag of the first zero crossing of each one's ACF without its straight line."""
    from ..signal.oscillation import acf, detrend  # noqa: PLC0415 (scipy: in the workers only)

    out = []
    for x in (op, pv):
        r = acf(detrend(x))
        below = np.flatnonzero(r[1:] <= 0.0)
        out.append(4.0 * float(below[0] + 1 if below.size else x.size))
    return out[0], out[1]


def too_short(samples: int, *, period: float | None = None,
              scales: tuple[float, float] | None = None, waiting: bool = False
              ) -> TooShort | None:
    """Why a window of ``samples`` is too short to judge (module doc), or None.

    ``period``: the loop's cycle in samples, where one is known; ``scales``: the window's
    :func:`movement_scales`, used where no period is known; ``waiting``: more samples are
    coming (the gateway's filling window) rather than the window being all there is."""
    by_movement: tuple[float, float] | None = None  # (scale, factor)
    if period is None and scales is not None:
        by_movement = ((max(scales), SEE_CYCLES) if waiting else (min(scales), PART_OF))
    needs: list[tuple[int, str, float | None]] = [(JUDGE_SAMPLES, "samples", None)]
    if period is not None and period > 0:
        needs.append((math.ceil(SEE_CYCLES * period), "cycles", period))
    if by_movement is not None:
        needs.append((math.ceil(by_movement[1] * by_movement[0]), "movement", by_movement[0]))
    failed = [need for need in needs if samples < need[0]]
    if not failed:
        return None
    _, basis, scale = failed[0]
    # what would be enough: every rule's need, the movement's at SEE_CYCLES
    need = max([n for n, _, _ in needs] +
               ([math.ceil(SEE_CYCLES * max(scales))] if by_movement and scales else []))
    return TooShort(samples, need, basis, scale, waiting)


def duration(seconds: float) -> str:
    """``0.4 s``, ``45 s``, ``4 min``, ``1 h 50 min``, ``2 h``."""
    if seconds < 10:
        return f"{seconds:.2g} s"
    s = round(seconds)
    if s < 120:
        return f"{s} s"
    minutes = round(s / 60)
    hours, rest = divmod(minutes, 60)
    if hours == 0:
        return f"{minutes} min"
    return f"{hours} h" + (f" {rest} min" if rest else "")
