"""The reason of a verdict in words: which tests said what."""

from __future__ import annotations

from .._assessment import Evidence, Verdict
from ..signal.cycle import Cycle
from ..signal.oscillation import MIN_PERIOD
from .combine import NO_STICTION_CONFIDENCE


def said(evidence: tuple[Evidence, ...], vote: int) -> str:
    names = [e.test for e in evidence if e.vote == vote]
    if not names:
        return "no test says so" if vote > 0 else "no test says otherwise"
    first = next(e.note for e in evidence if e.vote == vote)
    word = "for" if vote > 0 else "against"
    return f"{word}: {', '.join(names)} ({first})"


def not_stiction(cycle: Cycle, evidence: tuple[Evidence, ...], conf: float
                  ) -> tuple[Verdict, str]:
    """Verdict and reason when the confidence stays under the stiction threshold."""
    voted = [e for e in evidence if e.vote]
    if not cycle.regular and conf <= 0.5:
        src = cycle.pv if cycle.source == "PV" else cycle.op
        what = src.osc.reason if not cycle.cycling else (
            f"a cycle of {cycle.period or 0:.0f} samples, but irregular "
            f"(regularity {src.osc.regularity:.2f} <= 1)")
        return Verdict.NOT_OSCILLATING, (f"no regular oscillation in OP or PV ({what}); "
                                         f"confidence of stiction {conf:.2f}")
    if conf <= NO_STICTION_CONFIDENCE:
        return Verdict.NO_STICTION, (f"not stiction (confidence {conf:.2f}; "
                                     f"{said(evidence, -1)})")
    fast = ""
    if cycle.period is not None and cycle.period < MIN_PERIOD:
        fast = (f"; the cycle of {cycle.period:.1f} samples is too fast to see its shape: "
                "sample faster")
    if not voted:
        return Verdict.UNDETERMINED, (f"no test can tell on this window (confidence "
                                      f"{conf:.2f}){fast}")
    return Verdict.UNDETERMINED, (f"the tests disagree or are weak (confidence {conf:.2f}; "
                                  f"{said(evidence, 1)}; {said(evidence, -1)}){fast}")
