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
from stiction.diagnosis import adapt, network, shape
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


def test_analyze_at_a_sites_share_calls_what_adapt_calls() -> None:
    """A sticky valve of Table 6 exported every 10 s reads 0.63 alone (in the abstention
    band: undetermined); at a site where 60 % of the windows are sticky the same reading is
    0.92: stiction, by analyze with the site and by adapt from the assessment alike."""
    res = simulate(scenario("table6", tau=240.0), noise=0.02, seed=36, duration=3600.0)
    op, pv = res.op[::10], res.pv[::10]
    alone = analyze(op, pv, ts=10.0)
    net = next(e.value for e in alone.evidence if e.test == "shape_net")
    band_low, threshold = network.thresholds()
    assert net is not None and band_low + 0.2 < net < threshold - 0.04
    assert alone.verdict == Verdict.UNDETERMINED and alone.site == adapt.NONE
    site = adapt.Site(0.6, 40, adapt.estimate([]).source)
    there = analyze(op, pv, ts=10.0, site=site)
    assert there.verdict == Verdict.STICTION and there.confidence is not None
    assert there.confidence == pytest.approx(adapt.at_site(net, site)) and \
        there.confidence > threshold + 0.15
    assert (there.site, there.site_share) == (adapt.ADAPTED, 0.6)
    assert there.to_dict()["site"] == "adapted"
    e = next(e for e in there.evidence if e.test == "shape_net")
    assert e.value == net and e.vote == 1  # its own reading; the vote at the site
    (again,) = adapt.adapt([alone], site)
    assert again.verdict == there.verdict and again.confidence == pytest.approx(there.confidence)
