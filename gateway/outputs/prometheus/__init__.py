"""Prometheus output (the ``metrics`` config section): the per-loop series read from the
result store at scrape time (:mod:`.collector`), the engineer's findings (:mod:`.findings`),
the site's calibration of the confidence (:mod:`.site`) and the gateway's own series
(:mod:`.devices`), in one explicitly passed registry, served over HTTP by :mod:`.http`
(asyncio, bounded connections, one rendering thread).
"""

from __future__ import annotations

from typing import Any

from prometheus_client import CollectorRegistry, disable_created_metrics

from ...config.model import Config
from ...core.findings import FindingsBook
from ...core.sitecal import SiteBook
from ...wire.listener import ListenerStats
from ..base import Binding, Swap
from .collector import StoreCollector
from .devices import GatewayMetrics
from .findings import FindingsCollector
from .http import MetricsServer
from .plant import PlantCollector
from .site import SiteCollector

__all__ = ["GatewayMetrics", "MetricsServer", "PrometheusSink", "StoreCollector",
           "create_sink"]

disable_created_metrics()  # type: ignore[no-untyped-call]  # no _created series (they confuse dashboards, and promtool)


def create_sink(binding: Binding, *, registry: CollectorRegistry, metrics: GatewayMetrics,
                serve_http: bool = True, findings: FindingsBook | None = None,
                site: SiteBook | None = None, **_: Any) -> PrometheusSink:
    return PrometheusSink(registry, metrics, serve_http=serve_http, findings=findings,
                          site=site)


class PrometheusSink:
    """Registers the store collector, keeps each configured device's series, and (with
    ``serve_http``) serves /metrics on ``metrics.listen``; a reload that moves it binds the
    new address first (:meth:`prepare`)."""

    def __init__(self, registry: CollectorRegistry, metrics: GatewayMetrics, *,
                 serve_http: bool = True, findings: FindingsBook | None = None,
                 site: SiteBook | None = None) -> None:
        self.registry = registry
        self.findings = findings
        self.site = site
        self.metrics = metrics
        self.serve_http = serve_http
        self.collector: StoreCollector | None = None
        self.settings: Any = None  # the metrics section served
        self.devices: set[str] = set()
        self.http: MetricsServer | None = None
        self.stats = ListenerStats()
        metrics.track_server("metrics", self.stats)
        self.started = False

    @property
    def port(self) -> int | None:
        return self.http.port if self.http is not None else None

    def _server(self, settings: Any) -> MetricsServer:
        host, port = settings.listen
        return MetricsServer(self.registry, host, port,
                             max_connections=settings.max_connections,
                             idle_timeout_s=settings.idle_timeout_s, stats=self.stats,
                             store_series=lambda: self.collector)

    async def prepare(self, config: Config) -> Swap | None:
        new = config.metrics
        if self.http is None or self.settings is None or new.listen == self.settings.listen:
            return None
        server = self._server(new)
        await server.open()

        async def commit() -> None:  # serve on the new address, then let the old one go
            await server.start()
            old, self.http, self.settings = self.http, server, new
            if old is not None:
                await old.stop()

        return Swap(commit, server.stop)

    async def bind(self, binding: Binding) -> None:
        cfg = binding.config
        if self.collector is None:
            self.collector = StoreCollector(binding.store, self.findings)
            self.registry.register(self.collector)
            self.registry.register(PlantCollector(
                lambda: self.collector.store if self.collector is not None else None))
            if self.findings is not None:
                self.registry.register(FindingsCollector(self.findings))
            if self.site is not None:
                self.registry.register(SiteCollector(self.site))
        else:
            self.collector.store = binding.store
        self.metrics.set_identity(cfg.gateway.site, cfg.gateway.area)
        names = {d.name for d in cfg.devices}
        for name in sorted(self.devices - names):
            self.metrics.remove_device(name)
        for name in sorted(names - self.devices):
            self.metrics.add_device(name)
        self.devices = names
        if self.http is not None and self.settings is not None \
                and cfg.metrics.listen != self.settings.listen:  # not prepared: move now
            swap = await self.prepare(cfg)
            if swap is not None:
                await swap.commit()
        self.settings = cfg.metrics
        if self.http is None:
            return
        self.http.listener.max_connections = cfg.metrics.max_connections
        self.http.listener.idle_timeout_s = cfg.metrics.idle_timeout_s

    async def start(self) -> None:
        self.started = True
        await self._start_http()

    async def _start_http(self) -> None:
        if self.serve_http and self.started and self.settings is not None:
            server = self._server(self.settings)
            await server.start()
            self.http = server

    async def _stop_http(self) -> None:
        server, self.http = self.http, None
        if server is not None:
            await server.stop()

    async def stop(self) -> None:
        self.started = False
        await self._stop_http()
