"""stiction.ranking.calibration: the site's calibration fitted on findings (the rule: too few,
contradictory, no better, fitted) and what it does to an assessment."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from stiction import Assessment, Verdict
from stiction.ranking import SiteCalibration, fit_site, platt_fit, recalibrate, shipped

STICTION_AT, NO_STICTION_AT = 0.87, 0.5


def _site(n: int = 10, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A site whose good valves read high: sticky 0.92-0.99, good 0.80-0.95."""
    rng = np.random.default_rng(seed)
    c = np.r_[rng.uniform(0.92, 0.99, n), rng.uniform(0.80, 0.95, n)]
    return c, np.r_[np.ones(n), np.zeros(n)].astype(bool)


def test_the_shipped_thresholds_are_the_decisions() -> None:
    assert shipped() == (STICTION_AT, NO_STICTION_AT)


def test_too_few_findings_of_either_kind_keep_the_shipped_calibration() -> None:
    c, y = _site(4)
    cal = fit_site(c, y)
    assert not cal.used and cal.why.startswith("too few findings: 4 sticky, 4 not sticky")
    assert cal.apply(0.9) == 0.9
    assert not fit_site(c, y, min_each=4).why.startswith("too few")  # fitted, then judged


def test_findings_that_contradict_the_confidence_keep_the_shipped_calibration() -> None:
    c = np.r_[np.full(6, 0.2), np.full(6, 0.95)]  # the sticky valves read low
    y = np.r_[np.ones(6), np.zeros(6)].astype(bool)
    cal = fit_site(c, y)
    assert not cal.used and cal.why.startswith("contradictory findings")


def test_a_valve_found_both_ways_on_one_day_is_left_out_and_named() -> None:
    c, y = _site(6)
    keys = [f"V{k} 2024-05-01" for k in range(12)]
    c2, y2 = np.r_[c, 0.97], np.r_[y, False]
    cal = fit_site(c2, y2, keys=[*keys, "V0 2024-05-01"])
    assert cal.dropped == ("V0 2024-05-01",)
    assert (cal.sticky, cal.good) == (5, 6)
    assert "contradict another of their valve and day left out (V0 2024-05-01)" in cal.why


def test_a_fit_that_calls_worse_on_the_findings_keeps_the_shipped_one() -> None:
    # sticky valves at 0.99 and 0.91, a good one at 0.97, nine good ones at 0.6: the fit
    # reads the findings better (log loss) but, held out, keeps the false call at 0.97 and
    # drops the sticky ones at 0.91: 5 of 6 sticky against the shipped 10 of 11
    c = np.r_[np.full(5, 0.99), np.full(5, 0.91), [0.97], np.full(9, 0.6)]
    y = np.r_[np.ones(10), np.zeros(10)].astype(bool)
    cal = fit_site(c, y)
    assert cal.site is not None and cal.shipped is not None
    assert cal.site.log_loss < cal.shipped.log_loss
    assert (cal.site.hits, cal.site.calls, cal.shipped.hits, cal.shipped.calls) == (5, 6, 10, 11)
    assert not cal.used and cal.why.startswith("the fit's held-out calls are less precise")


def test_a_fit_that_reads_the_findings_no_better_keeps_the_shipped_one() -> None:
    # findings as the shipped confidence predicts them: held out, no fit beats it
    rng = np.random.default_rng(3)
    c = rng.uniform(0.02, 0.98, 60)
    y = rng.random(60) < c
    cal = fit_site(c, y)
    assert not cal.used and cal.why.startswith("the shipped calibration reads these")
    assert cal.site is not None and cal.shipped is not None
    assert cal.site.log_loss >= cal.shipped.log_loss


def test_a_site_whose_good_valves_read_high_is_recalibrated_and_its_calls_gain() -> None:
    c, y = _site(10)
    cal = fit_site(c, y)
    assert cal.used and cal.name == "site" and (cal.sticky, cal.good) == (10, 10)
    assert cal.scale > 0
    assert cal.site is not None and cal.shipped is not None
    assert cal.site.log_loss < cal.shipped.log_loss
    # the shipped confidence calls most of the good valves too; the site's, held out, fewer
    shipped_false = cal.shipped.calls - cal.shipped.hits
    site_false = cal.site.calls - cal.site.hits
    assert shipped_false >= 5 and site_false <= 1
    assert cal.apply(0.88) < STICTION_AT < cal.apply(0.985)
    # monotone: the site's order of its valves is the shipped one
    grid = np.linspace(0.01, 0.99, 50)
    assert np.all(np.diff([cal.apply(float(v)) for v in grid]) > 0)


def test_findings_that_separate_perfectly_give_a_finite_fit() -> None:
    x = np.r_[np.full(5, 3.0), np.full(5, -3.0)]
    y = np.r_[np.ones(5), np.zeros(5)]
    scale, offset = platt_fit(x, y)
    assert math.isfinite(scale) and math.isfinite(offset) and 1.0 < scale < 10.0


def _assessment(verdict: Verdict, conf: float, **kw: object) -> Assessment:
    return Assessment(verdict, f"{verdict}, confidence of stiction {conf:.2f}.",
                      oscillating=True, confidence=conf, **kw)  # type: ignore[arg-type]


def test_a_call_the_site_reads_under_the_threshold_is_withdrawn_with_its_size() -> None:
    cal = fit_site(*_site(10))
    sticky = _assessment(Verdict.STICTION, 0.9, fd=0.02, fs=0.03, jump=0.02, fd_op=2.0,
                         fs_op=3.0, cycles_used=4)
    a = recalibrate(sticky, cal, stiction_at=STICTION_AT, no_stiction_at=NO_STICTION_AT)
    assert a.verdict in (Verdict.UNDETERMINED, Verdict.NO_STICTION)
    assert a.fd is None and a.fs_op is None and a.cycles_used == 0 and a.sizes() is None
    assert a.confidence == pytest.approx(cal.apply(0.9))
    word = "undetermined" if a.verdict == Verdict.UNDETERMINED else "not stiction"
    assert a.reason.startswith(f"{word} at this site: the analysis said stiction at "
                               "confidence 0.90")
    assert "Calibration: this site's, from 20 findings: confidence 0.90 reads" in a.reason


def test_the_site_never_makes_a_call_nor_moves_what_the_travel_measured() -> None:
    cal = SiteCalibration(True, "fitted", scale=1.0, offset=5.0, sticky=5, good=5)
    up = recalibrate(_assessment(Verdict.UNDETERMINED, 0.7), cal, stiction_at=STICTION_AT,
                     no_stiction_at=NO_STICTION_AT)
    assert up.verdict == Verdict.UNDETERMINED and up.confidence > 0.99  # read high, no call
    raised = recalibrate(_assessment(Verdict.NO_STICTION, 0.3), cal, stiction_at=STICTION_AT,
                         no_stiction_at=NO_STICTION_AT)
    assert raised.verdict == Verdict.UNDETERMINED
    down = SiteCalibration(True, "fitted", scale=1.0, offset=-5.0, sticky=5, good=5)
    travel = _assessment(Verdict.STICTION, 0.95, fd=0.02, fd_op=2.0, position_use="used")
    kept = recalibrate(travel, down, stiction_at=STICTION_AT, no_stiction_at=NO_STICTION_AT)
    assert kept.verdict == Verdict.STICTION and kept.fd == 0.02
    calm = Assessment(Verdict.NOT_OSCILLATING, "calm", confidence=0.1)
    assert recalibrate(calm, down, stiction_at=STICTION_AT, no_stiction_at=0.5) is calm


def test_the_shipped_calibration_says_so_and_why() -> None:
    cal = fit_site(*_site(3))
    a = recalibrate(_assessment(Verdict.STICTION, 0.9), cal, stiction_at=STICTION_AT,
                    no_stiction_at=NO_STICTION_AT)
    assert a.verdict == Verdict.STICTION and a.confidence == 0.9
    assert a.reason.endswith("Calibration: shipped (too few findings: 3 sticky, 3 not sticky; "
                             "5 of each needed).")


def test_a_calibration_read_back_is_checked_field_by_field() -> None:
    cal = fit_site(*_site(10))
    assert SiteCalibration.from_dict(cal.to_dict()) == cal
    good = cal.to_dict()
    for broken in ({**good, "scale": "1"}, {**good, "scale": math.inf},
                   {**good, "sticky": -1}, {**good, "used": 1}, {**good, "extra": 0},
                   {**good, "site": {"log_loss": 1.0}}, {**good, "scale": -1.0},
                   {**good, "dropped": [3]}):
        with pytest.raises(ValueError, match="calibration"):
            SiteCalibration.from_dict(broken)
    assert SiteCalibration.from_dict(dataclasses.asdict(SiteCalibration(False, "x")) | {
        "dropped": []}).name == "shipped"
