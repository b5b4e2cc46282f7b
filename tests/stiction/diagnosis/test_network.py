"""Issue 36 item 2: the OP-PV shape network as evidence in `stiction.analyze` - its Platt
probability in the JSON evidence and in the reason, read on the cycle analyze found, not
read where the cycle is too fast for it, and a vote that backs a call of its own. (That the
numpy network equals PyTorch to 1e-6 on 100 windows: test_shape.py.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lab.sources import records
from stiction import Verdict, analyze
from stiction.diagnosis import network, shape
from stiction.diagnosis.analyze import analyze_details
from stiction.scenarios.named import scenario, simulate


def test_the_json_evidence_and_the_reason_carry_the_network_score() -> None:
    res = simulate(scenario("table4-case2"), noise=0.1, seed=3)
    d = analyze_details(res.op, res.pv, ts=1.0)
    a = d.assessment
    assert a.verdict == Verdict.STICTION
    shown = json.loads(json.dumps(a.to_dict()))
    (e,) = [e for e in shown["evidence"] if e["test"] == "shape_net"]
    _, threshold = network.thresholds()
    assert e["value"] > threshold + 0.2 and e["vote"] == 1
    assert e["note"] == f"the OP-PV shape network: {e['value']:.2f}"
    assert f"The OP-PV shape network: {e['value']:.2f}; the learned decision: " in a.reason
    (dec,) = [e for e in shown["evidence"] if e["test"] == "decision"]
    assert 0.0 <= dec["value"] <= 1.0
    # read on the clean window with the cycle analyze found, through the Platt map
    assert d.op is not None and d.pv is not None and d.cycle is not None
    net = shape.load()
    s = shape.score(d.op, d.pv, period=d.cycle.period, find=False, net=net)
    assert e["value"] == pytest.approx(float(shape.calibrated(net, s.logit)), abs=1e-12)


def test_a_cycle_too_fast_for_the_network_is_not_read() -> None:
    """The issue's good valve under a 5-minute load exported at 1 minute: 5 samples a cycle."""
    res = simulate(scenario("disturbance", dist_period=300.0), noise=0.05, seed=1,
                   duration=28800.0)
    a = analyze(res.op[::60], res.pv[::60], ts=60.0)
    (e,) = [e for e in a.evidence if e.test == "shape_net"]
    assert e.value is None and e.vote == 0 and "too fast" in e.note
    assert a.verdict != Verdict.STICTION
    assert "The OP-PV shape network:" not in a.reason


def test_a_plant_record_only_the_network_backs_is_called() -> None:
    """A record of the sticky plant valve 2411FIC20102 in which every test cannot tell: the
    network reads it at 0.87, far over its threshold, and its vote backs the call."""
    if not records.PLANT.exists():
        pytest.skip(f"plant records not found: {records.PLANT}")
    data = np.genfromtxt(records.PLANT / "STI_2411FIC20102_1004_0005.csv", delimiter=",",
                         names=True)
    a = analyze(data["op"], data["pv"], ts=10.0)
    votes = {e.test: e.vote for e in a.evidence if e.test != "decision"}
    net = next(e.value for e in a.evidence if e.test == "shape_net")
    _, threshold = network.thresholds()
    assert net is not None and net > threshold + 0.1
    assert a.verdict == Verdict.STICTION and a.confidence is not None
    assert [t for t, v in votes.items() if v > 0] == ["shape_net"]
    assert "Tests: stiction: shape_net;" in a.reason
