"""The site's calibration of the confidence (:mod:`gateway.core.sitecal`), read from the
site book's view at scrape time:

* ``stiction_site_calibration{state}``: 1 for the state of the calibration in force, 0 for
  the others: ``site`` (fitted on the crew's findings), ``too_few`` (findings of each kind
  short of ``analysis.site_calibration_min_each``), ``contradictory`` (the valves found fine
  score as high as the sticky ones), ``not_better`` (the fit reads the findings no better
  than the shipped calibration), ``off`` (``analysis.site_calibration: false`` or no
  findings file);
* ``stiction_site_findings_used``: the findings the fit used (those with a confidence on
  their day, less contradicting pairs);
* ``stiction_site_precision{calibration}`` and ``stiction_site_recall{calibration}``: on the
  findings, the share of the `stiction` calls (the confidence at or above the stiction
  threshold) that the crew found sticking, and the share of the sticky valves called:
  ``shipped`` with the shipped confidence, ``site`` with the site's, each finding predicted
  by a fit without it (leave-one-out); only where there are calls (precision) or sticky
  valves (recall) to count.
"""

from __future__ import annotations

from collections.abc import Iterator

from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ...core.sitecal import STATES, SiteBook

__all__ = ["SiteCollector"]


class SiteCollector(Collector):
    """Yields the site calibration's series from ``site``'s view."""

    def __init__(self, site: SiteBook) -> None:
        self.site = site

    def collect(self) -> Iterator[Metric]:
        view = self.site.view  # one immutable view
        cal = view.calibration
        state = GaugeMetricFamily(
            "stiction_site_calibration", "1 for the state of the calibration of the "
            "confidence in force: site (fitted on the crew's findings), too_few, "
            "contradictory, not_better (shipped kept, and why), off.", labels=["state"])
        for name in STATES:
            state.add_metric([name], 1.0 if view.state == name else 0.0)
        yield state
        yield GaugeMetricFamily(
            "stiction_site_findings_used", "Findings the site's calibration was fitted on "
            "(those with a confidence on their day).", value=float(cal.findings))
        precision = GaugeMetricFamily(
            "stiction_site_precision", "Share of the stiction calls on the findings that the "
            "crew found sticking: shipped confidence, or the site's (held out).",
            labels=["calibration"])
        recall = GaugeMetricFamily(
            "stiction_site_recall", "Share of the valves found sticking that were called "
            "stiction: shipped confidence, or the site's (held out).", labels=["calibration"])
        for name, scores in (("shipped", cal.shipped), ("site", cal.site)):
            if scores is None:
                continue
            if scores.precision is not None:
                precision.add_metric([name], scores.precision)
            if scores.recall is not None:
                recall.add_metric([name], scores.recall)
        yield precision
        yield recall
