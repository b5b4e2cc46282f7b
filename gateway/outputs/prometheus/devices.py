"""The gateway's own metrics: device up, poll duration/requests/errors, analysis duration,
config reload failures, the servers' connections, build info. Ordinary client objects in the
explicitly passed registry (a fresh one per gateway, so each test gets its own)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, Info
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ..._version import __version__
from ...errors import DeviceError
from ...wire.listener import CLOSE_REASONS, ListenerStats
from .collector import PREFIX

__all__ = ["RELOAD_STAGES", "GatewayMetrics", "ServerCollector"]

RELOAD_STAGES = ("read", "validate", "listen", "build")
"""Where a refused reload failed: reading/decoding the file, validating it, binding a new
listener, building the runtime."""


class GatewayMetrics:
    """The gateway's own metrics, in ``registry`` (a fresh one per gateway/test)."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.registry = registry
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
        self.reload_failures = Counter(
            f"{PREFIX}_config_reload_failures", "Config reloads refused (the running config "
            "kept), by stage.", ["stage"], registry=registry)
        for stage in RELOAD_STAGES:
            self.reload_failures.labels(stage=stage)
        self.servers = ServerCollector()
        registry.register(self.servers)
        self.build = Info(f"{PREFIX}_build", "Version of the gateway, and its site and area "
                          "(gateway.site, gateway.area) where the config names them.",
                          registry=registry)
        self.set_identity(None, None)

    def set_identity(self, site: str | None, area: str | None) -> None:
        """``stiction_build_info``'s labels: the version, and ``site``/``area`` if set."""
        labels = {"version": __version__, "site": site, "area": area}
        self.build.info({k: v for k, v in labels.items() if v})

    def track_server(self, name: str, stats: ListenerStats) -> None:
        """Publish a server's connection counts as ``server=name``."""
        self.servers.stats[name] = stats

    def add_device(self, name: str) -> None:
        """Create a device's series at zero so they exist before the first error."""
        self.device_up.labels(device=name).set(0)
        self.poll_requests.labels(device=name)
        self.poll_duration.labels(device=name)
        for kind in DeviceError.KINDS:
            self.poll_errors.labels(device=name, kind=kind)

    def remove_device(self, name: str) -> None:
        """Drop a device's series (it left the config on reload)."""
        for metric in (self.device_up, self.poll_requests, self.poll_duration):
            with contextlib.suppress(KeyError):
                metric.remove(name)
        for kind in DeviceError.KINDS:
            with contextlib.suppress(KeyError):
                self.poll_errors.remove(name, kind)



class ServerCollector(Collector):
    """Connections of the gateway's servers (``modbus``, ``metrics``), from their
    :class:`~gateway.wire.listener.ListenerStats` at scrape time."""

    def __init__(self) -> None:
        self.stats: dict[str, ListenerStats] = {}

    def collect(self) -> Iterator[Metric]:
        open_ = GaugeMetricFamily(f"{PREFIX}_server_connections",
                                  "Open client connections of a server.", labels=["server"])
        accepted = CounterMetricFamily(f"{PREFIX}_server_connections_accepted",
                                       "Client connections accepted.", labels=["server"])
        closed = CounterMetricFamily(
            f"{PREFIX}_server_connections_closed", "Client connections the server closed: "
            "over max_connections (limit), idle for idle_timeout_s (idle), garbage "
            "(protocol).", labels=["server", "reason"])
        for name, st in sorted(self.stats.items()):
            open_.add_metric([name], st.open)
            accepted.add_metric([name], st.accepted)
            for reason in CLOSE_REASONS:
                closed.add_metric([name, reason], st.closed[reason])
        yield from (open_, accepted, closed)
