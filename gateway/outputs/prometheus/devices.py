"""The gateway's own metrics: device up, poll duration/requests/errors, analysis duration,
build info. Ordinary client objects in the explicitly passed registry (a fresh one per
gateway, so each test gets its own)."""

from __future__ import annotations

import contextlib

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, Info

from ..._version import __version__
from ...errors import DeviceError
from .collector import PREFIX

__all__ = ["GatewayMetrics"]


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
        self.build = Info(f"{PREFIX}_build", "Version of the gateway, and its site and area "
                          "(gateway.site, gateway.area) where the config names them.",
                          registry=registry)
        self.set_identity(None, None)

    def set_identity(self, site: str | None, area: str | None) -> None:
        """``stiction_build_info``'s labels: the version, and ``site``/``area`` if set."""
        labels = {"version": __version__, "site": site, "area": area}
        self.build.info({k: v for k, v in labels.items() if v})

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

