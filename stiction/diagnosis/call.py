"""The call on a window from the learned decision and the OP-PV shape network together
(issue 36): which verdict of the stiction judgement, at which confidence, made by whom.

Measured on the fold that never saw a real record (``python -m lab decide``, docs/accuracy.md):
on the 80 plant records the learned decision (:mod:`.model`, trained on simulated and
Tennessee Eastman windows) ranked sticky records *below* good ones (AUC 0.39) and found 2 of
35; the network, trained on simulated loops only, ranked them at AUC 0.86 and found 16 of 35
at its threshold chosen on simulation, calling none of the 45 others. Every blend of the two
fitted on the development corpus leaned on the decision (it ranks the Tennessee Eastman
windows it was trained beside at 0.94-0.99) and fell to 0.61-0.77 on the plant; the decision
retrained with the network's score as one more feature reached 0.74. So the network leads
where it can read the window, and the decision keeps the calls the network does not object
to and the windows the network cannot read:

1. **The network read the window** (``net`` its Platt probability, :mod:`.network`): the
   confidence is ``net``.

   - ``net >= threshold``: ``stiction``, by the network (its +1 vote backs it in the evidence
     gate, :mod:`.gate`); where the decision calls stiction too, the confidence is the
     higher of the two;
   - the decision calls stiction (``decision >= stiction_at`` and a test backs it):
     ``stiction``, by the decision, at the decision's confidence, whatever the network
     reads (it misses some clean limit cycles the tests see: a Table 4 sticky flow loop
     read 0.05; vetoing the decision under ``band_low`` called 13 right and 5 wrong
     Tennessee Eastman windows fewer and 3 wrong realistic ones fewer, and changed nothing on
     the plant records);
   - ``band_low <= net < threshold``: ``undetermined`` (the abstention band: on held-out
     simulation 7-63 % of such windows were sticky), at ``net``; but ``no_stiction`` where
     the decision says not stiction too (``decision <= no_stiction_at``) and the tests
     agree (one at least says not stiction, none says stiction): of such windows 1 of 35 was
     sticky in the realistic simulations, none of 24 in the named scenarios, none on the
     plant records (a good valve under a sine load, which the network reads at 0.4, is not
     left undetermined);
   - ``net < band_low``: ``no_stiction`` (at most 5 % of such simulated windows were sticky),
     or ``undetermined`` where the decision says stiction and no test backs it.

2. **The network could not read it** (a cycle of fewer than 8 samples): the decision as
   before, ``stiction`` from ``stiction_at`` when a test made for such a cycle backs it,
   ``no_stiction`` up to ``no_stiction_at``, ``undetermined`` between.

``no_stiction`` is only a candidate here: :func:`stiction.diagnosis.reasons.not_stiction`
turns a window without a regular cycle into ``not_oscillating``. The rule is pure (numbers
and votes in, a :class:`Call` out); :func:`stiction.analyze` applies it to each window, and
:func:`stiction.diagnosis.adapt.adapt` again to a site's windows with the network's
probability moved to the site's share of sticky valves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from .._assessment import Assessment, Verdict
from . import gate, network
from . import model as learned

DECISION = "decision"
"""The evidence entry of the learned decision's probability (also
:data:`stiction.diagnosis.reasons.DECISION`)."""

__all__ = ["BY_BOTH", "BY_DECISION", "BY_NETWORK", "Call", "Thresholds", "call", "scale_of",
           "shipped"]

BY_NETWORK = "network"
BY_DECISION = "decision"
BY_BOTH = "both"


@dataclasses.dataclass(frozen=True)
class Thresholds:
    """The decision's (``stiction_at``, ``no_stiction_at``: model.json) and the network's
    (``threshold``, ``band_low``: shape.npz) thresholds."""

    stiction_at: float
    no_stiction_at: float
    threshold: float
    band_low: float


def shipped() -> Thresholds:
    """The thresholds as shipped (model.json, shape.npz)."""
    model = learned.load()
    band_low, threshold = network.thresholds()
    return Thresholds(model.stiction_at, model.no_stiction_at, threshold, band_low)


@dataclasses.dataclass(frozen=True)
class Call:
    """``verdict`` (``stiction``, ``undetermined`` or ``no_stiction``), ``confidence``;
    ``by`` who called stiction (:data:`BY_NETWORK`, :data:`BY_DECISION`, :data:`BY_BOTH`;
    None otherwise); ``unbacked`` why the decision's stiction was not backed by a test (the
    gate's phrase)."""

    verdict: Verdict
    confidence: float
    by: str | None = None
    unbacked: str | None = None


def call(decision: float, net: float | None, votes: Mapping[str, int], *, too_fast: bool,
         at: Thresholds) -> Call:
    """The call (module doc). ``votes``: the tests' votes by name, the network's left out
    (its vote is ``net``'s); ``too_fast``: the cycle is too fast to see its shape."""
    unbacked = gate.unbacked(votes, too_fast=too_fast) if decision >= at.stiction_at else None
    decides = decision >= at.stiction_at and unbacked is None
    if net is None:
        if decides:
            return Call(Verdict.STICTION, decision, BY_DECISION)
        if decision <= at.no_stiction_at:
            return Call(Verdict.NO_STICTION, decision)
        return Call(Verdict.UNDETERMINED, decision, unbacked=unbacked)
    if net >= at.threshold:
        return Call(Verdict.STICTION, max(net, decision) if decides else net,
                    BY_BOTH if decides else BY_NETWORK)
    if decides:
        return Call(Verdict.STICTION, decision, BY_DECISION)
    if net >= at.band_low:
        if decision <= at.no_stiction_at and _tests_say_not(votes):
            return Call(Verdict.NO_STICTION, net)
        return Call(Verdict.UNDETERMINED, net, unbacked=unbacked)
    if decision >= at.stiction_at:  # the decision says stiction, no test backs it
        return Call(Verdict.UNDETERMINED, net, unbacked=unbacked)
    return Call(Verdict.NO_STICTION, net)

def _tests_say_not(votes: Mapping[str, int]) -> bool:
    """At least one test says not stiction and none says stiction."""
    return any(v < 0 for v in votes.values()) and not any(v > 0 for v in votes.values())


def scale_of(a: Assessment, at: Thresholds | None = None) -> tuple[float, float]:
    """The thresholds ``(stiction, no_stiction)`` of the scale ``a``'s confidence is on: the
    network's (``threshold``, ``band_low``) where it is the network's probability, the
    decision's (``stiction_at``, ``no_stiction_at``) where it is the decision's (the network
    did not read the window, or the decision's call set it). For whatever compares the
    confidence with a threshold after the call (a site's recalibration, a hysteresis band)."""
    at = shipped() if at is None else at
    values = {e.test: e.value for e in a.evidence}
    net, dec = values.get(network.NAME), values.get(DECISION)
    if net is None or (dec is not None and a.confidence == dec):
        return at.stiction_at, at.no_stiction_at
    return at.threshold, at.band_low
