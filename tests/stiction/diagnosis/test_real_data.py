"""The verdict on real loops (issue 13's acceptance), through the same code the
``real_data`` benchmark prints: the plant records per tag and the Tennessee Eastman runs.

The data sit beside the repository in ../shared/data; under CI a missing folder fails.
"""

from __future__ import annotations

import collections
import os

import pytest

from lab.sources import records
from stiction import Verdict, analyze

CALLS = (Verdict.STICTION, Verdict.VALVE_NOT_RESPONDING)


def _need(path: object) -> None:
    if not records.PLANT.exists() or not records.TEP.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"real data missing under CI: {path}")
        pytest.skip(f"real data not found: {path}")


def test_plant_records_per_tag() -> None:
    """At least 3 of the 7 sticky tags called (2111FIC46005 among them, the textbook record;
    2411FIC10104 as a valve not responding), and no tag that is not sticky called by the
    majority of its records. Issue 13 asks for 4: the fourth would be 2411FIC20102, whose
    records each hold one stick-slip episode, and one episode alone made two of the three
    false calls on outside loops, so it is no longer a call (docs/accuracy.md)."""
    _need(records.PLANT)
    votes: dict[str, list[bool]] = collections.defaultdict(list)
    sticky: dict[str, bool] = {}
    for c in records.plant_cases():
        votes[c.group].append(analyze(c.op, c.pv, ts=c.ts).verdict in CALLS)
        sticky[c.group] = c.sticky
    called = {tag for tag, v in votes.items() if 2 * sum(v) >= len(v)}
    found = {tag for tag in called if sticky[tag]}
    false = {tag for tag in called if not sticky[tag]}
    assert "2111FIC46005" in found
    assert len(found) >= 3, sorted(found)
    assert not false, sorted(false)


def test_tep_sticky_reactor_valve_found_and_nothing_else() -> None:
    """Every IDV 14 run (the reactor cooling-water valve sticks) is called stiction; no
    normal, disturbed or propagated run is called (IDV 15 is barely visible, README)."""
    _need(records.TEP)
    wrong = []
    for c in records.tep_cases():
        v = analyze(c.op, c.pv, ts=c.ts).verdict
        if c.cause == "sticky (IDV 14)" and v != Verdict.STICTION:
            wrong.append((c.name, str(v)))
        if not c.sticky and v in CALLS:
            wrong.append((c.name, str(v)))
    assert not wrong
