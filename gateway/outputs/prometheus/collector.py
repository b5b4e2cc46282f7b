"""The per-loop series: a collector that reads a snapshot of the result store at scrape time.

No IO and no computation in ``collect()``: the scrape (on the HTTP server's thread) takes an
immutable :class:`~gateway.core.store.StoreSnapshot`, so a loop removed from the config
vanishes by itself and a result written meanwhile on the event loop is never half-read.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ...core.store import ResultStore
from ...wire.results import VERDICT_CODES

__all__ = ["PREFIX", "StoreCollector"]

PREFIX = "stiction"
VERDICTS = tuple(str(v) for v in VERDICT_CODES)


class StoreCollector(Collector):
    """Yields the per-loop series from the result store at each scrape."""

    def __init__(self, store: ResultStore) -> None:
        self.store = store

    def collect(self) -> Iterator[Metric]:
        st = self.store.snapshot()

        def fam(name: str, doc: str) -> GaugeMetricFamily:
            return GaugeMetricFamily(f"{PREFIX}_loop_{name}", doc, labels=["loop"])

        si = fam("stiction_index", "Stiction index of the latest assessment (He et al. 2007).")
        fd = fam("fd_ratio", "Dynamic friction fd, fraction of valve span (the Modbus "
                 "registers' and the CLI's % of span / 100).")
        fs = fam("fs_ratio", "Static friction fs, fraction of valve span (needs kp).")
        jump = fam("jump_ratio", "Valve jump J = K (fs - fd), K = 1.99, fraction of valve "
                   "span (needs kp).")
        period = fam("oscillation_period_seconds", "Oscillation period of the loop.")
        ts = fam("last_assessment_timestamp_seconds", "Unix time of the latest assessment.")
        fill = fam("window_fill_ratio", "Fraction of the window holding good samples.")
        conf = fam("confidence_ratio", "Confidence of stiction in the latest assessment, 0-1 "
                   "(the tests' weighted vote; >= 0.7 is a stiction verdict).")
        op = fam("op_percent", "Latest controller output, percent of valve span.")
        pv = fam("pv", "Latest process variable, process units.")
        verdict = GaugeMetricFamily(
            f"{PREFIX}_loop_verdict", "1 for the loop's current verdict, 0 for the others.",
            labels=["loop", "verdict"])
        for i, name in enumerate(st.loops):
            current = st.verdict_name(i)
            for v in VERDICTS:
                verdict.add_metric([name, v], 1.0 if v == current else 0.0)
            _add(op, name, st.latest_op[i])
            _add(pv, name, st.latest_pv[i])
            res = st.results[i]
            if res is None:
                continue
            a = res.assessment
            _add(si, name, a.stiction_index)
            size = a.sizes()
            if size is not None and size.of_span:  # % of span -> the base unit, 0-1
                _add(fd, name, size.fd / 100.0)
                _add(fs, name, None if size.fs is None else size.fs / 100.0)
                _add(jump, name, None if size.jump is None else size.jump / 100.0)
            _add(period, name, a.period_s)
            _add(ts, name, res.t)
            _add(fill, name, res.window_fill)
            _add(conf, name, a.confidence)
        yield from (si, fd, fs, jump, period, verdict, ts, fill, conf, op, pv)


def _add(family: GaugeMetricFamily, loop: str, value: float | None) -> None:
    if value is not None and math.isfinite(value):
        family.add_metric([loop], float(value))
