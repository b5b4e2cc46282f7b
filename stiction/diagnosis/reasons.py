"""The reason of a verdict in words: the confidence, what decided it and, for a sticky
valve, its size.

What decided: the tests whose part of the model's log-odds (:meth:`.model.Model.
contributions`) was largest, ``SAID`` at most for and ``SAID`` against, each in the words of
its own evidence note. Sentences, no parentheses around a test's note, so a reason never
nests them: "stiction, confidence 0.93. For: OP half cycles fit a triangle; 4 stick-slip
episodes ... Against: OP-PV cross-correlation is even ... Size: fd 2.7 % of span, ...".
"""

from __future__ import annotations

from collections.abc import Mapping

from .._assessment import Evidence, Verdict
from ..signal.cycle import Cycle
from ..signal.oscillation import MIN_PERIOD

__all__ = ["SAID", "WHAT", "decided", "not_stiction", "size_text", "stiction_head",
           "too_fast"]

SAID = 3
"""Tests named for, and against, at the most."""
MIN_PART = 0.05
"""A test whose part of the log-odds is smaller than this is not named."""
WHAT = {
    "si_op": "the shape of OP's half cycles", "si_pv": "the shape of PV's half cycles",
    "bicoherence": "the bicoherence of PV", "horch": "the OP-PV cross-correlation",
    "ellipse": "the OP-PV pattern", "kano": "where PV stood still while OP moved",
    "stick_slip": "stick-slip episodes", "hammerstein": "the valve fitted to PV",
    "fast_cycle": "how OP and PV are distributed", "cycle": "the cycle's period and "
    "regularity", "shape": "the shape of OP and PV"}
"""What each test (and the gates) looks at, said where its own note would not fit: a test
that did not vote one way can still weigh that way through its numbers."""


def decided(evidence: tuple[Evidence, ...], parts: Mapping[str, float]) -> str:
    """"For: ...; ... Against: ...": the strongest parts each way, in the words of the
    test's note where it voted that way, else by what the test looks at."""
    by_test = {e.test: e for e in evidence}
    out = []
    for word, sign in (("For", 1), ("Against", -1)):
        side = sorted(((sign * v, t) for t, v in parts.items() if sign * v >= MIN_PART),
                      reverse=True)[:SAID]
        said = []
        for _, t in side:
            e = by_test.get(t)
            said.append(e.note if e is not None and e.vote == sign else WHAT.get(t, t))
        if said:
            out.append(f"{word}: {'; '.join(said)}.")
    return " ".join(out) if out else "No test weighed either way."


def stiction_head(conf: float, evidence: tuple[Evidence, ...], parts: Mapping[str, float],
                  cycle: Cycle) -> str:
    return f"stiction, confidence {conf:.2f}. {decided(evidence, parts)}{too_fast(cycle)}"


def too_fast(cycle: Cycle) -> str:
    """A sentence when the cycle is too fast for its shape to be seen, else ''."""
    if cycle.period is not None and cycle.period < MIN_PERIOD:
        return (f" The cycle of {cycle.period:.1f} samples is too fast to see its shape: "
                "sample faster.")
    return ""


def size_text(fd: float, fs: float | None, unit: str, method: str, *, need_kp: bool) -> str:
    """The size sentence: ``unit`` is "% of span" or "OP units"."""
    fs_txt = "" if fs is None else f", fs {fs:.3g} {unit}"
    kp = " fs needs the process gain kp." if need_kp else ""
    span = "" if unit != "OP units" else " Give op_range for sizes in % of span."
    return f" Size: fd {fd:.3g} {unit}{fs_txt}, {method}.{kp}{span}"


def not_stiction(cycle: Cycle, evidence: tuple[Evidence, ...], conf: float,
                 parts: Mapping[str, float], no_stiction_at: float) -> tuple[Verdict, str]:
    """Verdict and reason when the confidence stays under the stiction threshold."""
    if not cycle.regular and conf <= 0.5:
        src = cycle.pv if cycle.source == "PV" else cycle.op
        what = src.osc.reason if not cycle.cycling else (
            f"a cycle of {cycle.period or 0:.0f} samples, but irregular, regularity "
            f"{src.osc.regularity:.2f} <= 1")
        return Verdict.NOT_OSCILLATING, (f"no regular oscillation in OP or PV: {what}; "
                                         f"confidence of stiction {conf:.2f}")
    if conf <= no_stiction_at:
        return Verdict.NO_STICTION, (f"not stiction, confidence of stiction {conf:.2f}. "
                                     f"{decided(evidence, parts)}")
    return Verdict.UNDETERMINED, (f"undetermined, confidence of stiction {conf:.2f}: between "
                                  f"what the tests tell apart. {decided(evidence, parts)}"
                                  f"{too_fast(cycle)}")

