"""The engineer's findings and the calls they are compared with (:mod:`gateway.core.findings`),
read from the findings book's view at scrape time: the site's series. The per-loop ones
(``stiction_loop_finding{loop, finding}``, 1, ``finding`` the loop's latest finding or
``none``, the label the alert rules copy so that Alertmanager can silence a loop confirmed
``ok``; ``stiction_loop_finding_timestamp_seconds{loop}``, the local midnight that began
that finding's day) are rendered with the other per-loop series (:mod:`.collector`).

* ``stiction_findings_total{verdict, finding}``: findings recorded, by the verdict the loop
  had on the finding's day (``unknown`` before the gateway's history of it): the product's
  own precision at this plant. A counter of the file's rows: a row taken out of the file
  lowers it (Prometheus reads that as a reset);
* ``stiction_findings_problems``: problem lines of the last read of the findings file (bad
  rows skipped, or a file that could not be read: the findings read before are kept).
"""

from __future__ import annotations

from collections.abc import Iterator

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ...core.findings import FindingsBook

__all__ = ["FindingsCollector"]


class FindingsCollector(Collector):
    """Yields the site's findings series from ``book``'s view."""

    def __init__(self, book: FindingsBook) -> None:
        self.book = book

    def collect(self) -> Iterator[Metric]:
        view = self.book.view  # one immutable view: never half of a reload
        total = CounterMetricFamily(
            "stiction_findings", "Findings recorded, by the verdict the loop had on the "
            "finding's day (unknown: before the gateway's history of the loop) and what "
            "was found.", labels=["verdict", "finding"])
        for (verdict, finding), n in sorted(view.counts.items()):
            total.add_metric([verdict, finding], float(n))
        yield total
        yield GaugeMetricFamily(
            "stiction_findings_problems", "Problems in the last read of the findings file "
            "(bad rows skipped; an unreadable file: the findings read before kept).",
            value=float(view.problems))
