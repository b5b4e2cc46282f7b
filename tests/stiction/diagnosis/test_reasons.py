"""Reasons that agree with their evidence (issue 32 item 4): the tests' votes as the evidence
table shows them, apart from what weighed most in the learned decision, one unit per
reason, and a new kind of evidence weighed, not voted."""

from __future__ import annotations

import re

import pytest
from detector_fixtures import cached_sim

from stiction import Assessment, Evidence, Verdict, analyze
from stiction.diagnosis.reasons import DECISION, VOTES, decided, votes_said

TABLE_WORDS = {1: "stiction", -1: "not stiction", 0: "cannot tell"}  # stiction analyze's


def _votes_said(reason: str) -> dict[str, str]:
    """The reason's "Tests: stiction: a, b; not stiction: c; cannot tell: d." as test ->
    vote word."""
    m = re.search(r"Tests: (.*?)\.(?: |$)", reason)
    assert m, reason
    out = {}
    for part in m.group(1).split("; "):
        word, _, tests = part.partition(": ")
        out.update(dict.fromkeys(tests.split(", "), word))
    return out


@pytest.fixture(scope="module")
def sticky() -> Assessment:
    """The loop `stiction analyze` reads in the CLI tests (table4-case2, noise 0.02, seed
    4): on main its reason said "Against: the OP-PV cross-correlation" while the table
    showed that test voting stiction, and gave fd in OP units and in % of span."""
    r = cached_sim("table4-case2", 0.02, 4)
    return analyze(r.op, r.pv, ts=1.0, kp=1.0, op_range=(0.0, 100.0))


def test_the_reason_says_each_tests_vote_as_the_table_shows_it(sticky: Assessment) -> None:
    assert sticky.verdict == Verdict.STICTION
    assert _votes_said(sticky.reason) == {e.test: TABLE_WORDS[e.vote] for e in sticky.evidence
                                          if e.test != DECISION}  # the decision is no test
    assert VOTES == TABLE_WORDS


def test_a_weight_against_its_own_vote_is_said_to_be_one(sticky: Assessment) -> None:
    weighed = sticky.reason.partition("Weighed most in the decision: ")[2]
    assert weighed, sticky.reason
    votes = {e.test: e.vote for e in sticky.evidence}
    assert votes["horch"] == 1  # the cross-correlation voted stiction ...
    against = weighed.partition("against: ")[2].partition(". Size")[0]
    assert "the OP-PV cross-correlation (horch, though it voted stiction)" in against
    # ... and no entry of the weighed part reads as a vote of its own
    assert "For:" not in sticky.reason and "Against:" not in sticky.reason


def _units(reason: str) -> set[str]:
    """The units that follow a number in a reason."""
    return set(re.findall(r"\d (OP units|% of span)", reason))


def test_one_unit_per_reason(sticky: Assessment) -> None:
    """On main: "a sticky valve (fd 23.7 OP units) ... Size: fd 26.9 % of span"."""
    assert _units(sticky.reason) == {"% of span"}, sticky.reason
    r = cached_sim("table4-case2", 0.02, 4)
    raw = analyze(r.op, r.pv, ts=1.0)  # no op_range: OP units only
    assert raw.verdict == Verdict.STICTION
    assert _units(raw.reason) == {"OP units"}, raw.reason


def test_every_entry_of_the_decision_is_weighed_not_voted() -> None:
    """A new kind of evidence (the lead's learned signal-shape score) is one more entry of
    what weighed, by its name, never a test's vote; unknown keys need no code here."""
    ev = (Evidence("si_op", 0.8, 1, "OP half cycles fit a triangle"),
          Evidence("horch", None, 0, "no regular cycle to correlate"))
    text = decided(ev, {"si_op": 0.9, "signal_shape": 1.4, "horch": -0.3, "cycle": 0.01})
    assert text == ("Tests: stiction: si_op; cannot tell: horch. Weighed most in the "
                    "decision: for stiction: signal_shape, the shape of OP's half cycles "
                    "(si_op); against: the OP-PV cross-correlation (horch).")
    assert votes_said(()) == "No test ran."
    assert decided(ev, {}).endswith("Nothing weighed much either way in the decision.")
