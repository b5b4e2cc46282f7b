"""The engineer's findings and the calls they are compared with (:mod:`gateway.core.findings`),
read from the findings book's view at scrape time.

* ``stiction_loop_finding{loop, finding}``: 1, one series per loop, ``finding`` its latest
  finding (``stiction``, ``deadband``, ``ok``, ``other``) or ``none``: the label the alert
  rules copy, so Alertmanager can silence a loop confirmed ``ok``;
* ``stiction_loop_finding_timestamp_seconds{loop}``: the local midnight that began the day
  of that finding (its age is ``time() -`` it), only for loops with a finding;
* ``stiction_findings_total{verdict, finding}``: findings recorded, by the verdict the loop
  had on the finding's day (``unknown`` before the gateway's history of it): the product's
  own precision at this plant. A counter of the file's rows: a row taken out of the file
  lowers it (Prometheus reads that as a reset);
* ``stiction_findings_problems``: problem lines of the last read of the findings file (bad
  rows skipped, or a file that could not be read: the findings read before are kept).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ...core.findings import FindingsBook, day_start

__all__ = ["FindingsCollector"]


class FindingsCollector(Collector):
    """Yields the findings' series for the loops ``loops()`` returns."""

    def __init__(self, book: FindingsBook, loops: Callable[[], tuple[str, ...]]) -> None:
        self.book = book
        self.loops = loops

    def collect(self) -> Iterator[Metric]:
        view = self.book.view  # one immutable view: never half of a reload
        latest = GaugeMetricFamily(
            "stiction_loop_finding", "1 for the loop's latest finding in the findings file "
            "(stiction, deadband, ok, other; none: no finding).", labels=["loop", "finding"])
        stamp = GaugeMetricFamily(
            "stiction_loop_finding_timestamp_seconds", "Unix time of the local midnight "
            "that began the day of the loop's latest finding.", labels=["loop"])
        for loop in self.loops():
            f = view.latest.get(loop)
            latest.add_metric([loop, "none" if f is None else f.finding], 1.0)
            if f is not None:
                stamp.add_metric([loop], day_start(f.date))
        total = CounterMetricFamily(
            "stiction_findings", "Findings recorded, by the verdict the loop had on the "
            "finding's day (unknown: before the gateway's history of the loop) and what "
            "was found.", labels=["verdict", "finding"])
        for (verdict, finding), n in sorted(view.counts.items()):
            total.add_metric([verdict, finding], float(n))
        problems = GaugeMetricFamily(
            "stiction_findings_problems", "Problems in the last read of the findings file "
            "(bad rows skipped; an unreadable file: the findings read before kept).",
            value=float(view.problems))
        yield latest
        yield stamp
        yield total
        yield problems
