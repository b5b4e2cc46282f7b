"""The detector interface and its registry: every test behind one small interface, and a new
test is one function and one registry line (here added in memory)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from detector_fixtures import cached_sim

from stiction import Evidence, Verdict, analyze
from stiction.detectors import registry
from stiction.detectors.base import NO_CYCLE, Detector, Fitted, Window, evidence_of
from stiction.diagnosis import network
from stiction.diagnosis.evidence import TESTS
from stiction.diagnosis.reasons import DECISION


def _sticky() -> tuple[np.ndarray, np.ndarray]:
    res = cached_sim("table4-case2", 0.02, 4)
    return res.op, res.pv


def test_every_registered_detector_is_a_documented_function_with_its_reference() -> None:
    assert registry.names() == TESTS
    assert len(set(TESTS)) == len(TESTS) == len(registry.DETECTORS)
    for d in registry.DETECTORS:
        assert d.reference, d.name
        assert inspect.getdoc(d.run), f"{d.name}: its function has no docstring"
        assert list(inspect.signature(d.run).parameters) == ["w"], d.name


def test_each_detector_names_its_evidence_as_registered() -> None:
    op, pv = _sticky()
    a = analyze(op, pv, ts=1.0)
    # the network and the learned decision's probability after them
    assert [e.test for e in a.evidence] == [*TESTS, network.NAME, DECISION]
    assert a.verdict == Verdict.STICTION  # the window every detector gets to see


def test_a_toy_detector_added_in_one_line_shows_in_analyze(
        monkeypatch: pytest.MonkeyPatch) -> None:
    op, pv = _sticky()
    before = analyze(op, pv, ts=1.0)
    seen: list[Window] = []

    def toy(w: Window) -> Evidence:
        seen.append(w)
        return Evidence("toy", float(w.op.size), 1, "a toy says stiction")

    monkeypatch.setattr(registry, "DETECTORS",
                        (*registry.DETECTORS, Detector("toy", toy, "a toy, for this test")))
    after = analyze(op, pv, ts=1.0)
    assert after.evidence[len(TESTS)] == Evidence("toy", float(op.size), 1,
                                                  "a toy says stiction")
    assert tuple(e for e in after.evidence if e.test != "toy") == before.evidence
    # the window a detector sees: the clean signals, the cycle the gates found, the noise
    (w,) = seen
    assert w.ts == 1.0 and not w.integrating and w.op.size == op.size
    assert w.period is not None and w.cycle.regular and min(w.noise) > 0
    # a test without trained weight is reported but weighs nothing
    assert after.confidence == before.confidence and after.verdict == before.verdict


def test_a_detector_that_misnames_its_evidence_is_refused(
        monkeypatch: pytest.MonkeyPatch) -> None:
    op, pv = _sticky()

    def liar(w: Window) -> Evidence:
        return Evidence("kano", None, 0, "claims to be another test")

    monkeypatch.setattr(registry, "DETECTORS",
                        (*registry.DETECTORS, Detector("liar", liar, "a wrong detector")))
    with pytest.raises(RuntimeError, match=r"liar gave 'kano'"):
        analyze(op, pv, ts=1.0)


def test_a_fit_gives_its_evidence_and_evidence_is_its_own() -> None:
    class Fit:
        def evidence(self) -> Evidence:
            return Evidence("fit", 2.0, -1, "a fit")

    e = Evidence("x", None, 0, NO_CYCLE)
    assert evidence_of(e) is e
    assert isinstance(Fit(), Fitted)
    assert evidence_of(Fit()) == Evidence("fit", 2.0, -1, "a fit")


def test_without_a_cycle_the_cycle_tests_abstain() -> None:
    rng = np.random.default_rng(3)
    op = np.cumsum(rng.normal(0, 0.1, 2000)) + 50
    pv = op + rng.normal(0, 0.5, 2000)
    a = analyze(op, pv, ts=1.0)
    by = {e.test: e for e in a.evidence}
    assert by["bicoherence"] == Evidence("bicoherence", None, 0, NO_CYCLE)
    assert by["ellipse"] == Evidence("ellipse", None, 0, NO_CYCLE)
