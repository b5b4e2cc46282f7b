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
from . import call, network
from .call import Call, Thresholds
from .enough import duration

__all__ = [
    "DECISION",
    "SAID",
    "VOTES",
    "WHAT",
    "decided",
    "decision_evidence",
    "network_said",
    "not_called",
    "size_text",
    "stiction_head",
    "too_fast",
    "too_fast_to_see",
    "votes_said",
    "weighed",
]

DECISION = call.DECISION
"""The evidence entry of the learned decision's probability (:func:`decision_evidence`): not
a test, so no test's vote in the reason nor in the evidence gate."""
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
    "regularity", "shape": "the shape of OP and PV", network.NAME: network.WHAT}
"""What each entry of the decision looks at: the tests, and the numbers of the gates (the
cycle, the shape of OP and PV). An entry missing here is named by its key."""


def votes_said(evidence: tuple[Evidence, ...]) -> str:
    """"Tests: stiction: a, b; not stiction: c; cannot tell: d." (module doc); the network
    is one of them, the learned decision (:data:`DECISION`) is not."""
    groups = [(word, [e.test for e in evidence if e.vote == vote and e.test != DECISION])
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
    return f"{votes_said(evidence)}{network_said(evidence)} {weight}"


def network_said(evidence: tuple[Evidence, ...]) -> str:
    """" The OP-PV shape network: 0.83; the learned decision: 0.41." where the network read
    the window (its Platt probability, :mod:`.network`; the decision's probability from its
    evidence :data:`DECISION`), else ''."""
    net, dec = _value(evidence, network.NAME), _value(evidence, DECISION)
    if net is None:
        return ""
    also = "" if dec is None else f"; the learned decision: {dec:.2f}"
    return f" {network.WHAT[0].upper()}{network.WHAT[1:]}: {net:.2f}{also}."


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


def decision_evidence(probability: float, stiction_at: float, no_stiction_at: float
                      ) -> Evidence:
    """The learned decision's probability as an evidence entry (:data:`DECISION`), its vote
    +1 from ``stiction_at``, -1 up to ``no_stiction_at``, so that the JSON evidence shows it
    beside the network's and a site's windows can be called again
    (:func:`stiction.diagnosis.adapt.adapt`)."""
    vote = 1 if probability >= stiction_at else -1 if probability <= no_stiction_at else 0
    return Evidence(DECISION, probability, vote,
                    f"the learned decision over the tests' numbers: {probability:.2f}")


def size_text(fd: float, fs: float | None, unit: str, method: str, *, need_kp: bool) -> str:
    """The size sentence: ``unit`` is "% of span" or "OP units"."""
    fs_txt = "" if fs is None else f", fs {fs:.3g} {unit}"
    kp = " fs needs the process gain kp." if need_kp else ""
    span = "" if unit != "OP units" else " Give op_range for sizes in % of span."
    return f" Size: fd {fd:.3g} {unit}{fs_txt}, {method}.{kp}{span}"


def not_called(c: Call, cycle: Cycle, evidence: tuple[Evidence, ...],
               parts: Mapping[str, float], *, reach_s: float, at: Thresholds
               ) -> tuple[Verdict, str]:
    """Verdict and reason of a window :func:`.call.call` did not call ``stiction``;
    ``reach_s``: the longest period the window can show (``not_oscillating`` says it). A
    window without a regular cycle at a confidence of 0.5 or less is ``not_oscillating``
    (unless the decision said stiction there)."""
    conf = c.confidence
    if not cycle.regular and conf <= 0.5 and c.unbacked is None:
        src = cycle.pv if cycle.source == "PV" else cycle.op
        what = src.osc.reason if not cycle.cycling else (
            f"a cycle of {cycle.period or 0:.0f} samples, but irregular, regularity "
            f"{src.osc.regularity:.2f} <= 1")
        return Verdict.NOT_OSCILLATING, (
            f"no regular oscillation in OP or PV with a period up to {duration(reach_s)}, "
            f"the longest this window can show: {what}; confidence of stiction {conf:.2f}")
    said = f"{decided(evidence, parts)}{too_fast(cycle)}"
    if c.verdict == Verdict.NO_STICTION:
        return Verdict.NO_STICTION, f"not stiction, confidence of stiction {conf:.2f}. {said}"
    dec = _value(evidence, DECISION)
    net = _value(evidence, network.NAME)
    if c.unbacked is not None:
        by = "," if net is None or dec is None else \
            f": the learned decision says stiction ({dec:.2f}),"
        return Verdict.UNDETERMINED, (
            f"undetermined, confidence of stiction {conf:.2f}{by} but {c.unbacked}: a call of "
            f"stiction needs a test that says so. {said}")
    between = "the tests" if net is None else \
        f"{network.WHAT} ({at.band_low:.2f}-{at.threshold:.2f})"
    return Verdict.UNDETERMINED, (f"undetermined, confidence of stiction {conf:.2f}: between "
                                  f"what {between} tells apart. {said}")


def _value(evidence: tuple[Evidence, ...], test: str) -> float | None:
    return next((e.value for e in evidence if e.test == test), None)
