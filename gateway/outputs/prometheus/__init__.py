"""Prometheus output (the ``metrics`` config section): the per-loop series read from the
result store at scrape time (:mod:`.collector`) and the gateway's own series
(:mod:`.devices`), in one explicitly passed registry, served over HTTP from a thread.
"""

from __future__ import annotations

import threading
from typing import Any
from wsgiref.simple_server import WSGIServer

from prometheus_client import CollectorRegistry, disable_created_metrics, start_http_server

from ..base import Binding
from .collector import StoreCollector
from .devices import GatewayMetrics

__all__ = ["GatewayMetrics", "PrometheusSink", "StoreCollector", "create_sink", "serve_metrics"]

disable_created_metrics()  # type: ignore[no-untyped-call]  # no _created series (they confuse dashboards, and promtool)


def create_sink(binding: Binding, *, registry: CollectorRegistry, metrics: GatewayMetrics,
                serve_http: bool = True, **_: Any) -> PrometheusSink:
    return PrometheusSink(registry, metrics, serve_http=serve_http)


def serve_metrics(registry: CollectorRegistry, host: str, port: int
                  ) -> tuple[WSGIServer, threading.Thread]:
    """Serve /metrics from a daemon thread; ``server.server_port`` is the bound port."""
    server, thread = start_http_server(port, addr=host, registry=registry)
    return server, thread


class PrometheusSink:
    """Registers the store collector, keeps each configured device's series, and (with
    ``serve_http``) serves /metrics on ``metrics.listen``, restarted when a reload moves it."""

    def __init__(self, registry: CollectorRegistry, metrics: GatewayMetrics, *,
                 serve_http: bool = True) -> None:
        self.registry = registry
        self.metrics = metrics
        self.serve_http = serve_http
        self.collector: StoreCollector | None = None
        self.listen: tuple[str, int] | None = None
        self.devices: set[str] = set()
        self._http: tuple[WSGIServer, threading.Thread] | None = None
        self.started = False

    @property
    def port(self) -> int | None:
        return self._http[0].server_port if self._http else None

    async def bind(self, binding: Binding) -> None:
        cfg = binding.config
        if self.collector is None:
            self.collector = StoreCollector(binding.store)
            self.registry.register(self.collector)
        else:
            self.collector.store = binding.store
        self.metrics.set_identity(cfg.gateway.site, cfg.gateway.area)
        names = {d.name for d in cfg.devices}
        for name in sorted(self.devices - names):
            self.metrics.remove_device(name)
        for name in sorted(names - self.devices):
            self.metrics.add_device(name)
        self.devices = names
        if cfg.metrics.listen != self.listen:
            self.listen = cfg.metrics.listen
            if self._http is not None:
                self._stop_http()
                self._start_http()

    async def start(self) -> None:
        self.started = True
        self._start_http()

    def _start_http(self) -> None:
        if self.serve_http and self.started and self.listen is not None:
            self._http = serve_metrics(self.registry, *self.listen)

    def _stop_http(self) -> None:
        assert self._http is not None
        server, thread = self._http
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
        self._http = None

    async def stop(self) -> None:
        self.started = False
        if self._http is not None:
            self._stop_http()
