"""The site's own calibration of the confidence, from the crew's findings: no IO (the
findings file is read by :mod:`gateway.config.findings`, this book kept on disk beside the
state file by :mod:`gateway.outputs.sitecal`).

A finding teaches the calibration the confidence its valve had when the crew went out: the
shipped confidence *in force when the finding's day began* (before that day's work could
change it), or, where the gateway had none for the loop then, its first of that day: the rule
of the verdict history (:class:`gateway.core.findings.VerdictHistory`).
:class:`ConfidenceHistory` keeps, per loop, that confidence for each day, for
:data:`RETENTION_DAYS`; a finding older than the history of its loop teaches nothing (it is
counted, not used).

:class:`SiteBook` holds the history and the calibration in force, fits it again when the
findings or the history change (:meth:`SiteBook.fit`, :func:`stiction.ranking.fit_site`:
a valve found sticking against one found fine, a dead band or another fault; at least
``analysis.site_calibration_min_each`` of each), and applies it to every assessment before
the verdict hysteresis (:meth:`SiteBook.calibrate`), the reason saying which calibration it
used. With ``analysis.site_calibration: false``, or without a findings file, assessments
pass as the analysis made them.
"""

from __future__ import annotations

import array
import bisect
import dataclasses
import datetime as dt
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from stiction import Assessment, Verdict
from stiction.ranking import SiteCalibration, fit_site, recalibrate

from ..config.findings import Finding
from ..config.model import AnalysisSettings
from .findings import local_day

__all__ = ["NO_FINDINGS", "OFF", "RETENTION_DAYS", "ConfidenceHistory", "SiteBook",
           "SiteView", "state_of"]

RETENTION_DAYS = 400
"""Days of each loop's confidence kept: a finding dated earlier teaches nothing."""
OFF = "analysis.site_calibration is false"
NO_FINDINGS = "no findings file in the config"
STATES = ("site", "too_few", "contradictory", "not_better", "off")
"""``stiction_site_calibration{state}``: the site's calibration in force, or why the shipped
one is: too few findings, findings that contradict the confidence, a fit that reads the
findings no better, or the site calibration turned off (or no findings file)."""


def state_of(cal: SiteCalibration, enabled: bool) -> str:
    """Which of :data:`STATES` ``cal`` is in."""
    if not enabled:
        return "off"
    if cal.used:
        return "site"
    if cal.why.startswith("contradictory"):
        return "contradictory"
    if cal.why.startswith("too few"):
        return "too_few"
    return "not_better"


@dataclasses.dataclass
class _Loop:
    """A loop's days (ordinals) and their confidences, as typed arrays: 12 bytes a day, so
    2,000 loops' full retention takes 10 MB, not the 50 of lists of Python numbers."""

    days: array.array[int] = dataclasses.field(default_factory=lambda: array.array("i"))
    conf: array.array[float] = dataclasses.field(default_factory=lambda: array.array("d"))
    t: float = float("-inf")
    latest: float = math.nan


class ConfidenceHistory:
    """Per loop, the shipped confidence in force when each day began (module doc); one
    entry a day at most, so a loop costs at most :data:`RETENTION_DAYS` entries."""

    def __init__(self, day_of: Callable[[float], int] = local_day) -> None:
        self.day_of = day_of
        self.loops: dict[str, _Loop] = {}
        self.dirty = False
        self.version = 0  # bumped whenever an answer of :meth:`on` may have changed

    def record(self, loop: str, t: float, confidence: float) -> None:
        """The loop's confidence at Unix time ``t`` (older than the latest: ignored)."""
        h = self.loops.setdefault(loop, _Loop())
        if t <= h.t or not math.isfinite(confidence):
            return
        day = self.day_of(t)
        if not h.days:
            h.days.append(day)
            h.conf.append(confidence)
            self.version += 1
        elif day > self.day_of(h.t):
            h.days.append(self.day_of(h.t) + 1)  # in force when the next day began
            h.conf.append(h.latest)
            self.version += 1
            if len(h.days) > RETENTION_DAYS + 1:
                del h.days[0], h.conf[0]
        h.t, h.latest = t, confidence
        self.dirty = True

    def on(self, loop: str, date: dt.date) -> float | None:
        """The confidence ``loop`` had on ``date`` (None: before its history)."""
        h = self.loops.get(loop)
        day = date.toordinal()
        if h is None or not h.days or day < h.days[0]:
            return None
        if day > self.day_of(h.t):
            return h.latest
        return h.conf[bisect.bisect_right(h.days, day) - 1]

    def to_data(self) -> dict[str, Any]:
        return {loop: {"days": [dt.date.fromordinal(d).isoformat() for d in h.days],
                       "conf": list(h.conf), "t": h.t, "latest": h.latest}
                for loop, h in self.loops.items() if h.days}

    def load(self, data: Mapping[str, Any]) -> None:
        """Take over what :meth:`to_data` wrote (checked by the reader), under what was
        recorded since start: a loop's newer history wins."""
        for loop, e in data.items():
            if loop in self.loops and self.loops[loop].t >= e["t"]:
                continue
            self.loops[loop] = _Loop(
                array.array("i", [dt.date.fromisoformat(d).toordinal() for d in e["days"]]),
                array.array("d", [float(c) for c in e["conf"]]), float(e["t"]),
                float(e["latest"]))
        self.version += 1


@dataclasses.dataclass(frozen=True)
class SiteView:
    """What the outputs show of the site's calibration: the calibration (``fitted``: when,
    Unix s), its state (:data:`STATES`), the findings dated before their loop's history."""

    calibration: SiteCalibration
    state: str
    fitted: float = 0.0
    unmatched: int = 0


class SiteBook:
    """The confidence history and the calibration in force (module doc)."""

    def __init__(self, settings: AnalysisSettings | None = None, *,
                 thresholds: tuple[float, float] | None = None,
                 history: ConfidenceHistory | None = None) -> None:
        self.settings = settings if settings is not None else AnalysisSettings()
        self.history = history if history is not None else ConfidenceHistory()
        self.thresholds = thresholds if thresholds is not None else _shipped()
        self.has_findings = False  # a findings file is configured
        self.view = SiteView(SiteCalibration(False, NO_FINDINGS), "off")
        self.fitted_on: tuple[int, tuple[Finding, ...]] | None = None  # (history, findings)

    @property
    def active(self) -> bool:
        """Whether assessments are calibrated by the site (or said to be shipped)."""
        return self.settings.site_calibration and self.has_findings

    def calibrate(self, loop: str, a: Assessment, t: float) -> Assessment:
        """Record ``a``'s shipped confidence and return ``a`` under the calibration in
        force (unchanged while the site calibration is not active)."""
        if a.confidence is not None and a.verdict != Verdict.WARMING_UP:
            self.history.record(loop, t, a.confidence)
        if not self.active:
            return a
        stiction_at, no_stiction_at = self.thresholds
        return recalibrate(a, self.view.calibration, stiction_at=stiction_at,
                           no_stiction_at=no_stiction_at)

    def stale(self, findings: Sequence[Finding]) -> bool:
        """Whether :meth:`fit` would see other inputs than the last time."""
        return self.fitted_on != (self.history.version, tuple(findings))

    def inputs(self, findings: Sequence[Finding]) -> tuple[list[float], list[bool],
                                                           list[str], int]:
        """Per finding with a confidence on its day: the confidence, whether the valve was
        found sticking, its key (loop and day); and how many had none."""
        conf, sticky, keys, unmatched = [], [], [], 0
        for f in findings:
            c = self.history.on(f.loop, f.date)
            if c is None:
                unmatched += 1
                continue
            conf.append(c)
            sticky.append(f.finding == "stiction")
            keys.append(f"{f.loop} {f.date.isoformat()}")
        return conf, sticky, keys, unmatched

    def fit(self, findings: Sequence[Finding], *, has_file: bool, now: float) -> SiteView:
        """Fit the site's calibration on ``findings`` (pure, may run in a thread); the view
        to :meth:`publish`."""
        if not self.settings.site_calibration:
            return SiteView(SiteCalibration(False, OFF), "off", now)
        if not has_file:
            return SiteView(SiteCalibration(False, NO_FINDINGS), "off", now)
        conf, sticky, keys, unmatched = self.inputs(findings)
        cal = fit_site(np.array(conf, dtype=np.float64), np.array(sticky, dtype=bool),
                       keys=keys, min_each=self.settings.site_calibration_min_each,
                       stiction_at=self.thresholds[0])
        if unmatched:
            cal = dataclasses.replace(cal, why=f"{cal.why}; {unmatched} finding(s) dated "
                                      "before the gateway's record of their loop not used")
        return SiteView(cal, state_of(cal, True), now, unmatched)

    def publish(self, view: SiteView, findings: Sequence[Finding], *, has_file: bool,
                version: int | None = None) -> None:
        """Put ``view`` in force (fitted on ``findings`` at history ``version``)."""
        self.has_findings = has_file
        self.view = view
        self.fitted_on = (self.history.version if version is None else version,
                          tuple(findings))


def _shipped() -> tuple[float, float]:
    from stiction.ranking import shipped  # noqa: PLC0415  (reads the decision's file)

    return shipped()
