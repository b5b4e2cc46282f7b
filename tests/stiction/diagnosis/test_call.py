"""Issue 36 items 2-3: the call from the learned decision and the OP-PV shape network
(stiction.diagnosis.call), the abstention band, and the site adaptation of a batch
(stiction.diagnosis.adapt): pure numbers and assessments in, far from every threshold."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from stiction import Assessment, Evidence, Verdict
from stiction.diagnosis import adapt, network
from stiction.diagnosis.call import (
    BY_BOTH,
    BY_DECISION,
    BY_NETWORK,
    Thresholds,
    call,
    scale_of,
    shipped,
)
from stiction.diagnosis.reasons import DECISION

AT = Thresholds(stiction_at=0.87, no_stiction_at=0.5, threshold=0.69, band_low=0.155)
FOR = {"si_op": 1, "horch": 0}  # a test says stiction
NONE = {"si_op": 0, "horch": 0}  # every test cannot tell
AGAINST = {"si_op": -1, "horch": 0}  # one says not, none says stiction


def test_the_shipped_thresholds_are_the_models() -> None:
    at = shipped()
    assert at.band_low < 0.5 < at.threshold < at.stiction_at
    assert (at.band_low, at.threshold) == network.thresholds()


@pytest.mark.parametrize(("decision", "net", "votes", "want"), [
    (0.10, 0.90, NONE, (Verdict.STICTION, 0.90, BY_NETWORK)),  # the network alone calls
    (0.97, 0.90, FOR, (Verdict.STICTION, 0.97, BY_BOTH)),  # both: the higher confidence
    (0.97, 0.40, FOR, (Verdict.STICTION, 0.97, BY_DECISION)),  # the network does not object
    (0.97, 0.40, NONE, (Verdict.UNDETERMINED, 0.40, None)),  # no test backs the decision
    (0.97, 0.05, FOR, (Verdict.STICTION, 0.97, BY_DECISION)),  # a test backs the decision
    (0.60, 0.40, FOR, (Verdict.UNDETERMINED, 0.40, None)),  # the abstention band
    (0.20, 0.40, NONE, (Verdict.UNDETERMINED, 0.40, None)),  # in the band, nothing against
    (0.20, 0.40, AGAINST, (Verdict.NO_STICTION, 0.40, None)),  # in the band, all say not
    (0.20, 0.05, FOR, (Verdict.NO_STICTION, 0.05, None)),  # under the band
    (0.97, 0.05, NONE, (Verdict.UNDETERMINED, 0.05, None)),  # under it, the decision says so
])
def test_where_the_network_reads_the_window_it_leads(
        decision: float, net: float, votes: dict[str, int],
        want: tuple[Verdict, float, str | None]) -> None:
    c = call(decision, net, votes, too_fast=False, at=AT)
    assert (c.verdict, c.confidence, c.by) == want


@pytest.mark.parametrize(("decision", "votes", "too_fast", "verdict", "unbacked"), [
    (0.95, FOR, False, Verdict.STICTION, False),
    (0.95, NONE, False, Verdict.UNDETERMINED, True),
    (0.95, FOR, True, Verdict.UNDETERMINED, True),  # too fast: only the fast-cycle test backs
    (0.95, {"fast_cycle": 1}, True, Verdict.STICTION, False),
    (0.70, FOR, False, Verdict.UNDETERMINED, False),
    (0.30, FOR, False, Verdict.NO_STICTION, False),
])
def test_where_it_cannot_the_decision_calls_as_before(
        decision: float, votes: dict[str, int], too_fast: bool, verdict: Verdict,
        unbacked: bool) -> None:
    c = call(decision, None, votes, too_fast=too_fast, at=AT)
    assert c.verdict == verdict and c.confidence == decision
    assert (c.unbacked is not None) == unbacked


def test_no_call_of_stiction_without_a_vote_for_it() -> None:
    """The evidence gate's property on the rule itself: over a grid of the two
    probabilities and every combination of votes, a `stiction` has a test voting +1 or the
    network at its threshold (its +1)."""
    grid = np.linspace(0.0, 1.0, 21)
    for votes in (FOR, NONE, AGAINST, {"fast_cycle": 1}, {"fast_cycle": -1, "si_op": 1}):
        for d in grid:
            for n in [None, *grid]:
                for fast in (False, True) if n is None else (False,):
                    c = call(float(d), n, votes, too_fast=fast, at=AT)
                    if c.verdict != Verdict.STICTION:
                        continue
                    backed = (n is not None and n >= AT.threshold) or (
                        votes.get("fast_cycle", 0) > 0 if fast else
                        any(v > 0 for v in votes.values()))
                    assert backed, (d, n, votes, fast)


def _window(net: float | None, decision: float, votes: dict[str, int],
            verdict: Verdict = Verdict.UNDETERMINED) -> Assessment:
    """An assessment as analyze gives it: the tests' evidence, the network's, the
    decision's."""
    ev = [Evidence(t, None, v, "a test") for t, v in votes.items()]
    ev.append(Evidence(network.NAME, net, 0 if net is None else network.vote_of(net),
                       "the network"))
    ev.append(Evidence(DECISION, decision, 0, "the decision"))
    conf = decision if net is None else net
    return Assessment(verdict, f"undetermined, confidence of stiction {conf:.2f}. Tests: x.",
                      oscillating=True, confidence=conf, evidence=tuple(ev))


def test_a_site_with_many_sticky_valves_moves_a_window_in_the_band_to_stiction() -> None:
    """Half of the batch reads far above the threshold: the site's share rises well above
    the simulation's, and a window at 0.6 (in the band alone) is called at the site."""
    batch = [_window(0.97, 0.3, NONE, Verdict.STICTION) for _ in range(20)] + \
        [_window(0.05, 0.1, AGAINST, Verdict.NO_STICTION) for _ in range(19)] + \
        [_window(0.60, 0.3, NONE)]
    site = adapt.site_of(batch)
    assert site.windows == 40 and site.share > site.source + 0.2
    moved = adapt.at_site(0.60, site)
    assert moved > AT.threshold + 0.1
    out = adapt.adapt(batch, site, AT)
    last = out[-1]
    assert last.verdict == Verdict.STICTION and last.confidence == pytest.approx(moved)
    assert last.site == adapt.ADAPTED and last.site_share == site.share
    assert "not sized here" in last.reason and last.sizes() is None
    net_e = next(e for e in last.evidence if e.test == network.NAME)
    assert net_e.value == 0.60 and net_e.vote == 1  # the window's own reading, the site's vote
    assert all(a.verdict == b.verdict for a, b in zip(out[:-1], batch[:-1], strict=True))
    assert adapt.site_of(out) == site  # the batch adapted reads the same share


def test_a_site_without_sticky_valves_leaves_a_weak_call_undetermined() -> None:
    """Every other window reads far under the band: the share falls, and a window just
    over the threshold alone (0.75, called stiction) is undetermined at the site."""
    sized = dataclasses.replace(_window(0.75, 0.3, NONE, Verdict.STICTION), fd=0.02,
                                fd_op=2.0, cycles_used=4, reason="stiction, confidence 0.75. "
                                "Tests: x. Size: fd 2 % of span.")
    batch = [_window(0.02, 0.1, AGAINST, Verdict.NO_STICTION) for _ in range(60)] + [sized]
    site = adapt.site_of(batch)
    assert site.share < site.source / 2
    last = adapt.adapt(batch, site, AT)[-1]
    assert adapt.at_site(0.75, site) < AT.threshold - 0.1
    assert last.verdict == Verdict.UNDETERMINED
    assert last.fd is None and last.fd_op is None and "Size:" not in last.reason


def test_what_the_network_did_not_read_keeps_its_call() -> None:
    batch = [_window(None, 0.95, {"fast_cycle": 1}, Verdict.STICTION),
             _window(0.97, 0.3, NONE, Verdict.STICTION)]
    out = adapt.adapt(batch, adapt.Site(0.9, 100, 0.18), AT)
    assert out[0].verdict == Verdict.STICTION and out[0].confidence == 0.95
    assert out[0].site == adapt.ADAPTED  # the batch was adapted; this window's call stands
    assert out[0].reason == batch[0].reason


def test_one_window_alone_is_scored_without_site_adaptation() -> None:
    a = _window(0.6, 0.3, NONE)
    assert a.site == adapt.NONE and a.site_share is None
    assert "site" not in a.to_dict() and "site_share" not in a.to_dict()
    alone = adapt.site_of([a])  # one window moves the share by a tenth at most
    assert abs(alone.share - alone.source) < 0.1 * alone.source + 0.05


def test_the_scale_of_a_confidence_is_its_sources() -> None:
    """For what compares a confidence with a threshold after the call (a site's
    recalibration, the gateway's hysteresis band): the network's thresholds where the
    confidence is its probability, the decision's where it is the decision's."""
    assert scale_of(_window(0.6, 0.3, NONE), AT) == (AT.threshold, AT.band_low)
    assert scale_of(_window(None, 0.95, FOR, Verdict.STICTION), AT) == \
        (AT.stiction_at, AT.no_stiction_at)
    by_decision = dataclasses.replace(_window(0.4, 0.97, FOR, Verdict.STICTION),
                                      confidence=0.97)
    assert scale_of(by_decision, AT) == (AT.stiction_at, AT.no_stiction_at)
