"""The reason of a verdict in words: the confidence, what the tests saw, what weighed most in
the decision and, for a sticky valve, its size.

Two different things are said apart, so that an engineer can check each against the
evidence table (``stiction analyze`` prints it under the reason):

- **What the tests saw**: every test's vote, exactly as the table shows it (``stiction``,
  ``not stiction``, ``cannot tell``), by the test's name: "Tests: stiction: si_op,
  stick_slip; not stiction: horch; cannot tell: si_pv, bicoherence, ...".
- **What weighed most in the decision**: the learned decision reads each test's numbers, not
  only its vote, so a test that voted stiction can weigh against it (its numbers sit where,
  in the corpus, the good valves were). These are the largest parts of the decision's
  log-odds (:meth:`.model.Model.contributions`), ``SAID`` at most for and ``SAID`` against,
  each named by what it looks at (:data:`WHAT`) and, for a test, its name; where a test's
  vote and its weight point opposite ways the reason says so. An entry that is not a test
  (the cycle, the shape of OP and PV, or any new learned score added to the decision) is one
  more entry here, by its :data:`WHAT` or its own name, never a vote.

One unit per reason: no test's note is quoted (some carry sizes in OP units); the size
sentence is the only one with a unit, the unit of the assessment's sizes.
"""

from __future__ import annotations

from collections.abc import Mapping

from .._assessment import Evidence, Verdict
from ..signal.cycle import Cycle
from ..signal.oscillation import MIN_PERIOD
from .enough import duration

__all__ = [
    "SAID",
    "VOTES",
    "WHAT",
    "decided",
    "not_stiction",
    "size_text",
    "stiction_head",
    "too_fast",
    "too_fast_to_see",
    "unbacked_text",
    "votes_said",
    "weighed",
]

SAID = 3
"""Entries named for, and against, at the most."""
MIN_PART = 0.05
"""An entry whose part of the log-odds is smaller than this is not named."""
VOTES = {1: "stiction", -1: "not stiction", 0: "cannot tell"}
"""A vote in the words of the evidence table."""
WHAT = {
    "si_op": "the shape of OP's half cycles", "si_pv": "the shape of PV's half cycles",
    "bicoherence": "the bicoherence of PV", "horch": "the OP-PV cross-correlation",
    "ellipse": "the OP-PV pattern", "kano": "where PV stood still while OP moved",
    "stick_slip": "stick-slip episodes", "hammerstein": "the valve fitted to PV",
    "fast_cycle": "how OP and PV are distributed", "cycle": "the cycle's period and "
    "regularity", "shape": "the shape of OP and PV"}
"""What each entry of the decision looks at: the tests, and the numbers of the gates (the
cycle, the shape of OP and PV). An entry missing here is named by its key."""


def votes_said(evidence: tuple[Evidence, ...]) -> str:
    """"Tests: stiction: a, b; not stiction: c; cannot tell: d." (module doc)."""
    groups = [(word, [e.test for e in evidence if e.vote == vote])
              for vote, word in VOTES.items()]
    said = [f"{word}: {', '.join(tests)}" for word, tests in groups if tests]
    return f"Tests: {'; '.join(said)}." if said else "No test ran."


def weighed(parts: Mapping[str, float]) -> tuple[list[str], list[str]]:
    """The entries that weighed most for and against stiction, strongest first."""
    return tuple(  # type: ignore[return-value]
        [key for _, key in sorted(((sign * v, key) for key, v in parts.items()
                                   if sign * v >= MIN_PART), reverse=True)[:SAID]]
        for sign in (1, -1))


def _entry(key: str, sign: int, votes: Mapping[str, int]) -> str:
    what = WHAT.get(key, key)
    if key not in votes:
        return what
    vote = votes[key]
    though = f", though it voted {VOTES[vote]}" if vote == -sign else ""
    return f"{what} ({key}{though})"


def decided(evidence: tuple[Evidence, ...], parts: Mapping[str, float]) -> str:
    """What the tests saw, then what weighed most in the decision (module doc)."""
    votes = {e.test: e.vote for e in evidence}
    for_, against = weighed(parts)
    sides = [f"{word}: {', '.join(_entry(k, sign, votes) for k in keys)}"
             for word, sign, keys in (("for stiction", 1, for_), ("against", -1, against))
             if keys]
    weight = (f"Weighed most in the decision: {'; '.join(sides)}." if sides else
              "Nothing weighed much either way in the decision.")
    return f"{votes_said(evidence)} {weight}"


def stiction_head(conf: float, evidence: tuple[Evidence, ...], parts: Mapping[str, float],
                  cycle: Cycle) -> str:
    return f"stiction, confidence {conf:.2f}. {decided(evidence, parts)}{too_fast(cycle)}"


def too_fast_to_see(cycle: Cycle) -> bool:
    """Whether the cycle is too fast for its shape to be seen (fewer than ``MIN_PERIOD``
    samples a period)."""
    return cycle.period is not None and cycle.period < MIN_PERIOD


def too_fast(cycle: Cycle) -> str:
    """A sentence when the cycle is too fast for its shape to be seen, else ''."""
    if cycle.period is not None and too_fast_to_see(cycle):
        return (f" The cycle of {cycle.period:.1f} samples is too fast to see its shape: "
                "sample faster.")
    return ""


def unbacked_text(conf: float, why: str, evidence: tuple[Evidence, ...],
                  parts: Mapping[str, float], cycle: Cycle) -> str:
    """The reason of a window the decision put at ``stiction`` and the evidence gate
    (:mod:`.gate`) did not: ``why`` says which rule it failed."""
    return (f"undetermined, confidence of stiction {conf:.2f}, but {why}: a call of stiction "
            f"needs a test that says so. {decided(evidence, parts)}{too_fast(cycle)}")


def size_text(fd: float, fs: float | None, unit: str, method: str, *, need_kp: bool) -> str:
    """The size sentence: ``unit`` is "% of span" or "OP units"."""
    fs_txt = "" if fs is None else f", fs {fs:.3g} {unit}"
    kp = " fs needs the process gain kp." if need_kp else ""
    span = "" if unit != "OP units" else " Give op_range for sizes in % of span."
    return f" Size: fd {fd:.3g} {unit}{fs_txt}, {method}.{kp}{span}"


def not_stiction(cycle: Cycle, evidence: tuple[Evidence, ...], conf: float,
                 parts: Mapping[str, float], no_stiction_at: float, *, reach_s: float
                 ) -> tuple[Verdict, str]:
    """Verdict and reason when the confidence stays under the stiction threshold;
    ``reach_s``: the longest period the window can show (``not_oscillating`` says it)."""
    if not cycle.regular and conf <= 0.5:
        src = cycle.pv if cycle.source == "PV" else cycle.op
        what = src.osc.reason if not cycle.cycling else (
            f"a cycle of {cycle.period or 0:.0f} samples, but irregular, regularity "
            f"{src.osc.regularity:.2f} <= 1")
        return Verdict.NOT_OSCILLATING, (
            f"no regular oscillation in OP or PV with a period up to {duration(reach_s)}, "
            f"the longest this window can show: {what}; confidence of stiction {conf:.2f}")
    if conf <= no_stiction_at:
        return Verdict.NO_STICTION, (f"not stiction, confidence of stiction {conf:.2f}. "
                                     f"{decided(evidence, parts)}")
    return Verdict.UNDETERMINED, (f"undetermined, confidence of stiction {conf:.2f}: between "
                                  f"what the tests tell apart. {decided(evidence, parts)}"
                                  f"{too_fast(cycle)}")
