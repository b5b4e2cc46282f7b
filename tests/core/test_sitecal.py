"""core.sitecal: the confidence in force when a finding's day began, and the site book's fit
and calibration of assessments (issue 39); outputs.sitecal.file: the book on disk, untrusted."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import pytest

from gateway.config.findings import Finding
from gateway.config.model import AnalysisSettings
from gateway.core.sitecal import RETENTION_DAYS, ConfidenceHistory, SiteBook
from gateway.outputs.sitecal.file import (
    CalibrationError,
    calibration_path,
    read_calibration,
    write_calibration,
)
from stiction import Assessment, Verdict
from stiction.ranking import fit_site

DAY = 86400.0


def _day(t: float) -> int:  # a UTC calendar, so the test runs in any time zone
    return dt.datetime.fromtimestamp(t, dt.UTC).date().toordinal()


T0 = dt.datetime(2024, 5, 1, 6, tzinfo=dt.UTC).timestamp()
D0 = dt.date(2024, 5, 1)


def test_a_findings_day_reads_the_confidence_in_force_when_it_began() -> None:
    h = ConfidenceHistory(day_of=_day)
    h.record("FIC101", T0, 0.6)  # the loop's first: 6:00 on May 1
    h.record("FIC101", T0 + 3600, 0.7)
    h.record("FIC101", T0 + DAY, 0.9)  # May 2
    h.record("FIC101", T0 + DAY + 60, 0.95)
    h.record("FIC101", T0 + DAY - 1e3, 0.1)  # older than the latest: ignored
    assert h.on("FIC101", D0 - dt.timedelta(days=1)) is None  # before its history
    assert h.on("FIC101", D0) == 0.6  # its first day: the day's first
    assert h.on("FIC101", D0 + dt.timedelta(days=1)) == 0.7  # May 1's last, in force then
    assert h.on("FIC101", D0 + dt.timedelta(days=9)) == 0.95  # since: the latest
    assert h.on("TIC301", D0) is None
    again = ConfidenceHistory(day_of=_day)
    again.load(json.loads(json.dumps(h.to_data())))
    assert [again.on("FIC101", D0 + dt.timedelta(days=k)) for k in range(3)] == [0.6, 0.7, 0.95]


def test_a_loop_keeps_at_most_its_retention_of_days() -> None:
    h = ConfidenceHistory(day_of=_day)
    for k in range(RETENTION_DAYS + 50):
        h.record("L", T0 + k * DAY, 0.5)
    assert len(h.loops["L"].days) == RETENTION_DAYS + 1
    assert h.on("L", D0) is None  # forgotten


def _finding(loop: str, finding: str) -> Finding:
    return Finding(loop, D0, finding)


def test_the_book_pairs_findings_with_their_days_confidence_and_calibrates() -> None:
    book = SiteBook(AnalysisSettings(site_calibration_min_each=3), thresholds=(0.87, 0.5),
                    history=ConfidenceHistory(day_of=_day))
    for k in range(3):
        book.history.record(f"S{k}", T0, 0.99)
        book.history.record(f"G{k}", T0, 0.9)
    found = [*(_finding(f"S{k}", "stiction") for k in range(3)),
             *(_finding(f"G{k}", f) for k, f in enumerate(("ok", "deadband", "other"))),
             _finding("NEW", "ok")]  # no confidence on its day
    conf, sticky, keys, unmatched = book.inputs(found)
    assert (conf, sticky, unmatched) == ([0.99] * 3 + [0.9] * 3, [True] * 3 + [False] * 3, 1)
    assert keys[0] == "S0 2024-05-01"
    view = book.fit(found, has_file=True, now=T0)
    assert view.state == "site" and view.unmatched == 1
    assert "1 finding(s) dated before the gateway's record of their loop not used" in \
        view.calibration.why
    call = Assessment(Verdict.STICTION, "sticky.", confidence=0.91, fd=0.02, fd_op=2.0)
    assert book.calibrate("X", call, T0) is call  # no findings file bound yet: as analysed
    book.publish(view, found, has_file=True)
    assert not book.stale(found)
    got = book.calibrate("X", call, T0 + 60)
    assert got.verdict != Verdict.STICTION and got.fd is None
    assert book.history.on("X", D0) == 0.91  # the shipped confidence recorded
    book.history.record("S0", T0 + DAY, 0.98)  # a new day: the inputs may have changed
    assert book.stale(found)
    assert book.fit(found, has_file=False, now=T0).state == "off"
    book.settings = AnalysisSettings(site_calibration=False)
    assert book.fit(found, has_file=True, now=T0).calibration.why == \
        "analysis.site_calibration is false"


def test_the_calibration_file_round_trips_and_is_checked(tmp_path: Path) -> None:
    assert calibration_path("state/gw.state") == Path("state/gw.calibration")
    assert calibration_path("gwstate") == Path("gwstate.calibration")
    h = ConfidenceHistory(day_of=_day)
    h.record("FIC101", T0, 0.6)
    h.record("FIC101", T0 + DAY, 0.9)
    cal = fit_site([0.99] * 5 + [0.9] * 5, [True] * 5 + [False] * 5)
    path = tmp_path / "gw.calibration"
    write_calibration(path, h.to_data(), cal, T0, T0 + 5)
    loops, back, fitted = read_calibration(path, max_loops=10)
    assert back == cal and fitted == T0 and loops == json.loads(json.dumps(h.to_data()))
    good = json.loads(path.read_text())
    broken = [
        ("foreign", {**good, "format": "other"}),
        ("foreign", {**good, "version": 2}),
        ("corrupt", {**good, "fitted": "now"}),
        ("corrupt", {**good, "calibration": {**good["calibration"], "scale": "1"}}),
        ("corrupt", {**good, "loops": {"FIC101": {**good["loops"]["FIC101"],
                                                  "conf": [0.6, 1.5]}}}),
        ("corrupt", {**good, "loops": {"FIC101": {**good["loops"]["FIC101"],
                                                  "days": ["2024-05-02", "2024-05-01"]}}}),
        ("corrupt", {**good, "loops": {"FIC101": {**good["loops"]["FIC101"], "x": 1}}}),
        ("corrupt", {**good, "loops": {f"L{k}": good["loops"]["FIC101"] for k in range(11)}}),
    ]
    for kind, data in broken:
        path.write_text(json.dumps(data))
        with pytest.raises(CalibrationError) as err:
            read_calibration(path, max_loops=10)
        assert err.value.kind == kind, data
    path.write_bytes(b"\xff\xfe not json")
    with pytest.raises(CalibrationError, match="not readable JSON"):
        read_calibration(path, max_loops=10)
    path.write_text(json.dumps(good) + " " * 2_000_000)
    with pytest.raises(CalibrationError, match="more than the"):
        read_calibration(path, max_loops=1)
