"""The plant-wide groups' series (:mod:`gateway.core.plant`), one per group, read from the
result store's plant view at scrape time; the per-loop group and role are in
:mod:`.collector`.

``stiction_plant_group_period_seconds{group, source}`` and
``stiction_plant_group_loops{group, source}``: ``group`` is the group's number (as in the
result registers), ``source`` its source loop, empty when no loop read is the source (the
cycle enters from outside). A group that ends vanishes.

``stiction_plant_changes_total{change}``: the plant view's changes published since the
gateway started (``group_appeared``, ``group_ended``, ``source``, ``role``: a loop became or
stopped being a source or a follower) and ``held``: analysis rounds in which a changed view
was held back because it had not yet held for ``plant.hold_rounds`` rounds
(:mod:`gateway.core.planthold`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ...core.plantview import CHANGES
from ...core.store import ResultStore

__all__ = ["PlantCollector"]


class PlantCollector(Collector):
    """Yields one series per plant-wide group of the store ``store()`` returns."""

    def __init__(self, store: Callable[[], ResultStore | None]) -> None:
        self.store = store

    def collect(self) -> Iterator[Metric]:
        st = self.store()
        groups = st.plant.groups if st is not None else ()
        period = GaugeMetricFamily(
            "stiction_plant_group_period_seconds",
            "Period of a plant-wide group's shared cycle (source: the loop whose valve drives "
            "it, empty when no loop read is the source).", labels=["group", "source"])
        loops = GaugeMetricFamily(
            "stiction_plant_group_loops",
            "Loops in a plant-wide group (its source and followers).",
            labels=["group", "source"])
        for g in groups:
            labels = [str(g.number), g.source or ""]
            period.add_metric(labels, g.period_s)
            loops.add_metric(labels, float(len(g.loops)))
        yield period
        yield loops
        changes = CounterMetricFamily(
            "stiction_plant_changes",
            "Plant-view changes published (group_appeared, group_ended, source, role) and "
            "rounds a change was held back (held), since the gateway started.",
            labels=["change"])
        counts = st.plant.changes if st is not None else {}
        for change in CHANGES:
            changes.add_metric([change], float(counts.get(change, 0)))
        yield changes
