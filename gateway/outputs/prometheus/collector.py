"""Prometheus metrics: a collector that reads the result store, plus the gateway's own.

Every per-loop series is produced at scrape time from :class:`~gateway.store.ResultStore`
(no IO, no computation), so a loop removed from the config vanishes by itself. The gateway's
own metrics (device up, poll duration/requests/errors, analysis duration, build info) are
ordinary client objects registered in the same, explicitly passed, registry.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator
from wsgiref.simple_server import WSGIServer

from prometheus_client import (
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    Info,
    disable_created_metrics,
    start_http_server,
)
from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ... import __version__
from ...core.store import VERDICT_CODES, ResultStore

__all__ = ["GatewayMetrics", "StoreCollector", "serve_metrics"]

PREFIX = "stiction"
VERDICTS = tuple(str(v) for v in VERDICT_CODES)

disable_created_metrics()  # type: ignore[no-untyped-call]  # no _created series (they confuse dashboards, and promtool)


class StoreCollector(Collector):
    """Yields the per-loop series from the result store at each scrape."""

    def __init__(self, store: ResultStore) -> None:
        self.store = store

    def collect(self) -> Iterator[Metric]:
        st = self.store

        def fam(name: str, doc: str) -> GaugeMetricFamily:
            return GaugeMetricFamily(f"{PREFIX}_loop_{name}", doc, labels=["loop"])

        si = fam("stiction_index", "Stiction index of the latest assessment (He et al. 2007).")
        fd = fam("fd_ratio", "Dynamic friction fd, fraction of valve span.")
        fs = fam("fs_ratio", "Static friction fs, fraction of valve span (needs kp).")
        jump = fam("jump_ratio", "Valve jump J = fs - fd, fraction of valve span.")
        period = fam("oscillation_period_seconds", "Oscillation period of the loop.")
        ts = fam("last_assessment_timestamp_seconds", "Unix time of the latest assessment.")
        fill = fam("window_fill_ratio", "Fraction of the window holding good samples.")
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
            _add(fd, name, a.fd)
            _add(fs, name, a.fs)
            _add(jump, name, a.jump)
            _add(period, name, a.period_s)
            _add(ts, name, res.t)
            _add(fill, name, res.window_fill)
        yield from (si, fd, fs, jump, period, verdict, ts, fill, op, pv)


def _add(family: GaugeMetricFamily, loop: str, value: float | None) -> None:
    if value is not None and math.isfinite(value):
        family.add_metric([loop], float(value))


class GatewayMetrics:
    """The gateway's own metrics, in ``registry`` (a fresh one per gateway/test)."""

    def __init__(self, registry: CollectorRegistry, store: ResultStore | None = None) -> None:
        self.registry = registry
        self.collector: StoreCollector | None = None
        if store is not None:
            self.collector = StoreCollector(store)
            registry.register(self.collector)
        self.device_up = Gauge(f"{PREFIX}_device_up", "1 while the device answers polls.",
                               ["device"], registry=registry)
        self.poll_duration = Histogram(
            f"{PREFIX}_poll_duration_seconds", "Wall time of one poll of a device.", ["device"],
            buckets=(0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0),
            registry=registry)
        self.poll_requests = Counter(f"{PREFIX}_poll_requests", "Protocol requests sent.",
                                     ["device"], registry=registry)
        self.poll_errors = Counter(f"{PREFIX}_poll_errors", "Failed polls by kind.",
                                   ["device", "kind"], registry=registry)
        self.analysis_duration = Histogram(
            f"{PREFIX}_analysis_duration_seconds", "Worker time to analyse one loop window.",
            buckets=(0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5),
            registry=registry)
        self.build = Info(f"{PREFIX}_build", "Version of the gateway.", registry=registry)
        self.build.info({"version": __version__})

    def add_device(self, name: str) -> None:
        """Create a device's series at zero so they exist before the first error."""
        self.device_up.labels(device=name).set(0)
        self.poll_requests.labels(device=name)
        self.poll_duration.labels(device=name)
        for kind in ("connect", "timeout", "exception", "auth", "protocol"):
            self.poll_errors.labels(device=name, kind=kind)


    def set_store(self, store: ResultStore) -> None:
        """Serve the per-loop series from ``store`` from now on (after a reload)."""
        if self.collector is None:
            self.collector = StoreCollector(store)
            self.registry.register(self.collector)
        else:
            self.collector.store = store

    def remove_device(self, name: str) -> None:
        """Drop a device's series (it left the config on reload)."""
        for metric in (self.device_up, self.poll_requests, self.poll_duration):
            with contextlib.suppress(KeyError):
                metric.remove(name)
        for kind in ("connect", "timeout", "exception", "auth", "protocol"):
            with contextlib.suppress(KeyError):
                self.poll_errors.remove(name, kind)


def serve_metrics(registry: CollectorRegistry, host: str, port: int
                  ) -> tuple[WSGIServer, threading.Thread]:
    """Serve /metrics from a daemon thread; ``server.server_port`` is the bound port."""
    server, thread = start_http_server(port, addr=host, registry=registry)
    return server, thread
