"""The gateway's own metrics: device up (and why it is down), refused requests, poll
duration/requests/errors, missed ticks, poll lateness and whether a device keeps its
schedule, analysis duration, verdict changes published and held back, config reload
failures, state-file writes, the servers' connections and errors, build info. Ordinary
client objects in the explicitly passed registry (a fresh one per gateway, so each test gets
its own)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, Info
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

from ..._version import __version__
from ...core.hysteresis import OUTCOMES
from ...errors import DeviceError
from ...wire.listener import CLOSE_REASONS, ERROR_STAGES, ListenerStats
from .collector import PREFIX

__all__ = ["RELOAD_STAGES", "STATE_SET_ASIDE", "GatewayMetrics", "ServerCollector"]

RELOAD_STAGES = ("read", "validate", "listen", "build")
"""Where a refused reload failed: reading/decoding the file, validating it, binding a new
listener, building the runtime."""
STATE_SET_ASIDE = ("corrupt", "foreign", "unreadable")
"""Why a state file was not restored at start: a field out of bounds (set aside), not ours
(set aside), not a regular file or no answer in time (``unreadable``: left in place)."""
LATENESS_BUCKETS = (0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)


class GatewayMetrics:
    """The gateway's own metrics, in ``registry`` (a fresh one per gateway/test)."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.registry = registry
        self.device_up = Gauge(f"{PREFIX}_device_up", "1 while the device answers polls.",
                               ["device"], registry=registry)
        self.down_reason = Gauge(
            f"{PREFIX}_device_down_reason", "1 while the device is down (device_up 0), "
            "labelled with why, in the log's words: no connection, no answer, login refused, "
            "protocol error, unit id N not served, illegal data address...; no series "
            "while it is up.", ["device", "reason"], registry=registry)
        self.refused = Counter(
            f"{PREFIX}_poll_refused_requests", "Requests the device refused (a Modbus "
            "exception), by the exception in words (illegal data address, unit id N not "
            "served...).", ["device", "exception"], registry=registry)
        self._reasons: dict[str, str] = {}  # device -> its down_reason label
        self._refusals: set[tuple[str, str]] = set()  # refused's label sets
        self.poll_duration = Histogram(
            f"{PREFIX}_poll_duration_seconds", "Wall time of one poll of a device.", ["device"],
            buckets=(0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0),
            registry=registry)
        self.poll_requests = Counter(f"{PREFIX}_poll_requests", "Protocol requests sent.",
                                     ["device"], registry=registry)
        self.poll_errors = Counter(f"{PREFIX}_poll_errors", "Failed polls by kind.",
                                   ["device", "kind"], registry=registry)
        self.missed_ticks = Counter(
            f"{PREFIX}_poll_missed_ticks", "Ticks of the poll schedule that passed while a "
            "poll overran (each a gap row in the windows).", ["device"], registry=registry)
        self.poll_lateness = Histogram(
            f"{PREFIX}_poll_lateness_seconds", "How late a poll started after its tick was "
            "due.", ["device"], buckets=LATENESS_BUCKETS, registry=registry)
        self.behind = Gauge(
            f"{PREFIX}_device_behind_schedule", "1 while polls of the device cannot keep "
            "its poll_interval_s: a tenth of its ticks missed within the last minute (10 "
            "intervals if longer).", ["device"], registry=registry)
        self.analysis_duration = Histogram(
            f"{PREFIX}_analysis_duration_seconds", "Worker time to analyse one loop window.",
            buckets=(0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5),
            registry=registry)
        self.verdict_changes = Counter(
            f"{PREFIX}_verdict_changes", "Loop verdicts through the verdict hysteresis "
            "(verdict_hysteresis): changes published, and rounds in which a change was held "
            "back (a new verdict not yet held for its rounds, or a judgement held while its "
            "window warms up again).", ["outcome"], registry=registry)
        for outcome in OUTCOMES:
            self.verdict_changes.labels(outcome=outcome)
        self.reload_failures = Counter(
            f"{PREFIX}_config_reload_failures", "Config reloads refused (the running config "
            "kept), by stage.", ["stage"], registry=registry)
        for stage in RELOAD_STAGES:
            self.reload_failures.labels(stage=stage)
        self.state_write_failures = Counter(
            f"{PREFIX}_state_write_failures", "State-file writes that failed (e.g. a full "
            "disk).", registry=registry)
        self.state_last_write = Gauge(
            f"{PREFIX}_state_last_write_timestamp_seconds", "Unix time of the last "
            "state-file write that succeeded.", registry=registry)
        self.state_set_aside = Counter(
            f"{PREFIX}_state_file_set_aside", "State files set aside, or left unread, at start "
            "(the gateway started empty), by reason.", ["reason"], registry=registry)
        for reason in STATE_SET_ASIDE:
            self.state_set_aside.labels(reason=reason)
        self.state_clock_back = Gauge(
            f"{PREFIX}_state_clock_back_seconds", "How far the wall clock was behind the "
            "state file's last write when the gateway started (0: not behind). Above 0 the "
            "clock stepped back across the restart (an NTP correction after a reboot?): the "
            "downtime was unknown, restored as a gap, and sequence numbers moved on as "
            "after a kill.", registry=registry)
        self.servers = ServerCollector()
        registry.register(self.servers)
        self.build = Info(f"{PREFIX}_build", "Version of the gateway, and its site and area "
                          "(gateway.site, gateway.area) where the config names them.",
                          registry=registry)
        self.set_identity(None, None)

    def count_verdict(self, outcome: str) -> None:
        """One outcome of the verdict hysteresis (:data:`~gateway.core.hysteresis.OUTCOMES`)."""
        self.verdict_changes.labels(outcome=outcome).inc()

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
        self.behind.labels(device=name).set(0)
        for metric in (self.poll_requests, self.poll_duration, self.missed_ticks,
                       self.poll_lateness):
            metric.labels(device=name)
        for kind in DeviceError.KINDS:
            self.poll_errors.labels(device=name, kind=kind)

    def set_down_reason(self, name: str, reason: str | None) -> None:
        """``stiction_device_down_reason{device=name, reason=...} 1``, or no series (None:
        the device is up)."""
        old = self._reasons.pop(name, None)
        if old is not None and old != reason:
            with contextlib.suppress(KeyError):
                self.down_reason.remove(name, old)
        if reason is not None:
            self._reasons[name] = reason
            self.down_reason.labels(device=name, reason=reason).set(1)

    def count_refused(self, name: str, exception: str) -> None:
        self._refusals.add((name, exception))
        self.refused.labels(device=name, exception=exception).inc()

    def remove_device(self, name: str) -> None:
        """Drop a device's series (it left the config on reload)."""
        for metric in (self.device_up, self.poll_requests, self.poll_duration, self.behind,
                       self.missed_ticks, self.poll_lateness):
            with contextlib.suppress(KeyError):
                metric.remove(name)
        for kind in DeviceError.KINDS:
            with contextlib.suppress(KeyError):
                self.poll_errors.remove(name, kind)
        self.set_down_reason(name, None)
        for dev, exception in [k for k in self._refusals if k[0] == name]:
            self._refusals.discard((dev, exception))
            with contextlib.suppress(KeyError):
                self.refused.remove(dev, exception)



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
            "for a newcomer over max_connections (limit: one that never completed a "
            "request; unread: one not reading its answers; busiest: the highest request "
            "rate), idle for idle_timeout_s (idle), garbage (protocol), an error while "
            "answering (error).", labels=["server", "reason"])
        errors = CounterMetricFamily(
            f"{PREFIX}_server_errors", "Unexpected errors of a server (logged), by stage: "
            "answering a request, rendering the metrics page.", labels=["server", "stage"])
        for name, st in sorted(self.stats.items()):
            open_.add_metric([name], st.open)
            accepted.add_metric([name], st.accepted)
            for reason in CLOSE_REASONS:
                closed.add_metric([name, reason], st.closed[reason])
            for stage in ERROR_STAGES:
                errors.add_metric([name, stage], st.errors.get(stage, 0))
        yield from (open_, accepted, closed, errors)
