"""``analyze(..., position=...)``: the verdict from the valve's travel where the position is
usable (stiction sized by band and slip, a valve that follows is no_stiction whatever PV
does, one that does not follow is valve_not_responding), OP and PV's otherwise."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from valve_loops import run_loops

import stiction
from stiction import ParameterError, Verdict
from stiction.diagnosis.analyze import analyze_details
from stiction.diagnosis.travel import BY_OP_PV, BY_TRAVEL, MEASURED, NOT_USED
from stiction.models.valves import HeValve, KanoValve


def _travel_note(a: stiction.Assessment) -> str:
    (e,) = [e for e in a.evidence if e.test == "travel"]
    return e.note


def test_stiction_measured_from_the_travel_is_sized_by_band_and_slip() -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, pv_noise=0.05, position_noise=0.05)
    a = stiction.analyze(r.op, r.pv, ts=1.0, op_range=(0.0, 100.0), k=1.0,
                         position=r.position)
    assert a.verdict == Verdict.STICTION
    assert MEASURED in a.reason
    assert _travel_note(a).startswith(BY_TRAVEL)
    assert a.confidence == pytest.approx(1.0)
    size = a.sizes()
    assert size is not None
    assert size.unit == "% of span"
    d = size.to_dict()
    assert d["band"] == pytest.approx(5.0, rel=0.1)
    assert d["slip"] == pytest.approx(1.0, rel=0.1)
    assert d["fs"] == pytest.approx(3.0, rel=0.1)  # (band + slip) / 2
    assert d["fd"] == pytest.approx(2.0, rel=0.1)  # fs - slip / K, K = 1


def test_without_op_range_the_sizes_are_in_op_units() -> None:
    (r,) = run_loops(HeValve(0.05, 0.04, 1.99), 1, position_noise=0.05)
    a = stiction.analyze(r.op, r.pv, ts=1.0, position=r.position)
    size = a.sizes()
    assert size is not None
    assert size.unit == "OP units"
    assert size.band == pytest.approx(10.0 - 1.99, rel=0.1)
    assert size.slip == pytest.approx(1.99, rel=0.1)


def test_a_good_valve_in_a_disturbed_loop_is_no_stiction() -> None:
    (r,) = run_loops(HeValve(0.0, 0.0, 1.0), 1, pv_noise=0.05, position_noise=0.05,
                     dist_amp=0.05, dist_period=300.0)
    a = stiction.analyze(r.op, r.pv, ts=1.0, op_range=(0.0, 100.0), position=r.position)
    assert a.verdict == Verdict.NO_STICTION
    assert MEASURED in a.reason
    assert a.oscillating
    assert _travel_note(a).startswith(BY_TRAVEL)
    assert a.sizes() is None


def test_a_good_valve_decides_whatever_pv_does() -> None:
    """PV frozen (a dead transmitter): OP and PV alone say bad_data; the valve follows OP."""
    (r,) = run_loops(HeValve(0.0, 0.0, 1.0), 1, pv_noise=0.05, dist_amp=0.05,
                     dist_period=300.0)
    frozen = np.full_like(r.pv, 50.0)
    assert stiction.analyze(r.op, frozen, ts=1.0).verdict != Verdict.NO_STICTION
    a = stiction.analyze(r.op, frozen, ts=1.0, position=r.position)
    assert a.verdict == Verdict.NO_STICTION


def test_a_valve_that_does_not_follow_is_not_responding() -> None:
    """A valve stuck for good (fs 100 % of span): integral action ramps OP 16 % while the
    position and PV hold within their noise."""
    (r,) = run_loops(HeValve(1.0, 0.9, 1.0), 1, pv_noise=0.05, position_noise=0.05,
                     sp_step=1.0, ti=200.0)
    assert np.ptp(r.op) > 10.0
    a = stiction.analyze(r.op, r.pv, ts=1.0, op_range=(0.0, 100.0), position=r.position)
    assert a.verdict == Verdict.VALVE_NOT_RESPONDING
    assert MEASURED in a.reason
    assert a.position_use == "used"


@pytest.mark.parametrize("position", ["nan", "gappy"])
def test_an_unusable_position_keeps_the_op_pv_diagnosis(position: str) -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, pv_noise=0.05)
    pos = np.full_like(r.op, np.nan)
    if position == "gappy":
        pos[::2] = r.position[::2]
    kw = {"ts": 1.0, "op_range": (0.0, 100.0)}
    plain = stiction.analyze(r.op, r.pv, **kw)  # type: ignore[arg-type]
    a = stiction.analyze(r.op, r.pv, position=pos, **kw)  # type: ignore[arg-type]
    assert _travel_note(a).startswith(BY_OP_PV)
    assert a.position_use == "could_not_tell"
    assert a.reason.startswith(plain.reason)
    assert f"{NOT_USED}: " in a.reason.removeprefix(plain.reason)
    assert dataclasses.replace(a, evidence=a.evidence[:-1], reason=plain.reason,
                               position_use=None) == plain


def test_no_position_is_exactly_the_op_pv_diagnosis() -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, pv_noise=0.05)
    d = analyze_details(r.op, r.pv, ts=1.0)
    assert d.travel is None
    assert all(e.test != "travel" for e in d.assessment.evidence)
    assert d.assessment == stiction.analyze(r.op, r.pv, ts=1.0, position=None)


def test_a_position_of_another_length_is_named() -> None:
    with pytest.raises(ParameterError, match="position"):
        stiction.analyze(np.zeros(200), np.zeros(200), ts=1.0, position=np.zeros(10))


def test_assessment_round_trips_band() -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, position_noise=0.05)
    a = stiction.analyze(r.op, r.pv, ts=1.0, op_range=(0.0, 100.0), position=r.position)
    assert a.band is not None
    assert stiction.Assessment.from_dict(a.to_dict()) == a
