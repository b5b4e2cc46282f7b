"""The /metrics HTTP server: asyncio connections on a bounded
:class:`~gateway.wire.listener.Listener` (``metrics.max_connections``,
``metrics.idle_timeout_s``, a few requests per turn of the event loop), not a thread per
connection.

``GET`` (or ``HEAD``) of ``/metrics`` or ``/`` answers the registry's exposition: the
``Accept`` header picks OpenMetrics or the text format, ``name[]`` query parameters restrict
the series (as prometheus_client's own server does), gzip when accepted. Rendering runs in
one worker thread (the collectors read a snapshot of the store; the per-loop series are
rendered by :meth:`.collector.StoreCollector.page`, 3-5 times faster than the client
library's encoder); scrapes that arrive while a
rendering is under way share it, and a page serves later scrapes of the same kind for
:data:`RENDER_REST` times as long as it took to render, so however many scrapers there are,
rendering takes at most a quarter of the time (it holds the interpreter that the pollers
share). Requests of one connection are answered in order, one at a time (pipelined ones
wait in its bounded buffer); while a client does not read its answers, none of its requests
is answered.

Other paths get 404, other methods 405, an ``Accept`` header the exposition cannot use 406,
a request with a body or a malformed request 400, headers over 8 KiB 431 (the last three
close the connection); a request line may end in CRLF or a bare LF. A rendering that fails
answers 500, is logged (rate-limited by cause) and counted
(``stiction_server_errors_total{server="metrics",stage="render"}``).
"""

from __future__ import annotations

import asyncio
import gzip
import logging
import re
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any
from urllib.parse import parse_qs

from prometheus_client import CollectorRegistry
from prometheus_client.exposition import choose_encoder

from ...wire.listener import Conn, Listener, ListenerStats
from .collector import StoreCollector

__all__ = ["MAX_HEAD_BYTES", "RENDER_REST", "MetricsServer"]

log = logging.getLogger("gateway.server")

MAX_HEAD_BYTES = 8192
RENDER_REST = 3.0
"""A page serves scrapes of the same kind for this many times its rendering time."""
_REASONS = {200: "OK", 400: "Bad Request", 404: "Not Found", 405: "Method Not Allowed",
            406: "Not Acceptable", 431: "Request Header Fields Too Large",
            500: "Internal Server Error"}
_HEAD_END = re.compile(rb"\r?\n\r?\n")
Page = tuple[int, str, bytes, bool]  # status, content type, body, gzipped
Key = tuple[str, bool, tuple[str, ...]]


class NotAcceptable(ValueError):
    """An ``Accept`` header the exposition cannot use."""


def negotiate(accept: str) -> tuple[Callable[[Any], bytes], str]:
    """prometheus_client's choice of encoder and content type for ``accept``; NotAcceptable
    if it cannot parse it (it raised TypeError on ``version=abc``)."""
    try:
        return choose_encoder(accept)
    except Exception as exc:
        raise NotAcceptable(f"{type(exc).__name__}") from exc


class _HttpConn(Conn):
    """One client connection: requests in, one at a time, answers out."""

    in_limit = 2 * MAX_HEAD_BYTES

    def ready(self) -> bool:
        return len(self.buffer) > MAX_HEAD_BYTES or _HEAD_END.search(self.buffer) is not None

    def serve(self, n: int) -> int:
        done = 0
        while done < n and not self.closed and not self.blocked:
            end = _HEAD_END.search(self.buffer)
            if end is None or end.start() > MAX_HEAD_BYTES:
                if end is not None or len(self.buffer) > MAX_HEAD_BYTES:
                    self._reply(431, b"request headers too large\n", keep=False)
                    done += 1
                break
            head = bytes(self.buffer[:end.start()])
            del self.buffer[:end.end()]
            done += 1
            try:
                self._request(head.decode("latin-1"))
            except Exception as exc:  # answered, counted, logged: never the event loop's
                self.listener.failed("request", exc)
                self.busy = False
                self._reply(500, b"the request could not be answered\n", keep=False)
        return done

    def _request(self, head: str) -> None:
        lines = [line.rstrip("\r") for line in head.split("\n")]
        request = lines[0].split(" ")
        if len(request) != 3 or not request[2].startswith("HTTP/1."):
            self._reply(400, b"malformed request\n", keep=False)
            return
        method, target, version = request
        headers = {}
        for line in lines[1:]:
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        if headers.get("content-length", "0") != "0" or "transfer-encoding" in headers:
            self._reply(400, b"no request body expected\n", keep=False)
            return
        connection = headers.get("connection", "").lower()
        keep = connection != "close" if version == "HTTP/1.1" else connection == "keep-alive"
        if method not in ("GET", "HEAD"):
            self._reply(405, b"only GET and HEAD\n", keep=False)
            return
        head_only = method == "HEAD"
        path, _, query = target.partition("?")
        if path not in ("/", "/metrics"):
            self._reply(404, b"not found: try /metrics\n", keep=keep, head=head_only)
            return
        names = tuple(sorted(parse_qs(query).get("name[]", [])))
        gz = "gzip" in headers.get("accept-encoding", "").lower()
        server: MetricsServer = self.listener.owner
        try:
            future = server.page(headers.get("accept", ""), gz, names)
        except NotAcceptable as exc:
            log.warning("%s: cannot use the client's Accept header", f"metrics server, "
                        f"Accept: {exc}")
            self._reply(406, b"unusable Accept header: try text/plain or "
                        b"application/openmetrics-text; version=1.0.0\n", keep=keep,
                        head=head_only)
            return
        self.busy = True
        future.add_done_callback(lambda f: self._rendered(f, keep, head_only))

    def _rendered(self, future: asyncio.Future[Page], keep: bool, head: bool) -> None:
        self.busy = False
        if self.closed:
            return
        try:
            self._answer(future, keep, head)
        except Exception as exc:  # a callback's exception would reach the event loop
            self.listener.failed("request", exc)
            self.drop("error")

    def _answer(self, future: asyncio.Future[Page], keep: bool, head: bool) -> None:
        if future.cancelled() or future.exception() is not None:
            self._reply(500, b"the metrics could not be rendered\n", keep=False)
            return
        status, ctype, body, gz = future.result()
        self._reply(status, body, keep=keep, head=head, ctype=ctype, gz=gz)
        if not self.buffer:
            self.pending_since = None
        self.listener.wake(self)  # a pipelined request, in a later turn

    def _reply(self, status: int, body: bytes, *, keep: bool, head: bool = False,
               ctype: str = "text/plain; charset=utf-8", gz: bool = False) -> None:
        lines = [f"HTTP/1.1 {status} {_REASONS.get(status, '')}", f"Content-Type: {ctype}",
                 f"Content-Length: {len(body)}",
                 f"Connection: {'keep-alive' if keep else 'close'}"]
        if gz:
            lines.append("Content-Encoding: gzip")
        self.write(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + (b"" if head else body))
        self.served()
        if not keep and self.transport is not None and not self.closed:
            if status >= 400:
                self.listener.stats.closed["protocol"] += 1
            self.closed = True
            self.transport.close()  # after the answer is sent


class MetricsServer:
    """Serves ``registry`` over HTTP on ``host:port`` (see the module docstring)."""

    def __init__(self, registry: CollectorRegistry, host: str, port: int, *,
                 max_connections: int, idle_timeout_s: float,
                 stats: ListenerStats | None = None,
                 store_series: Callable[[], StoreCollector | None] | None = None) -> None:
        self.registry = registry
        self.store_series = store_series  # the per-loop series, rendered fast
        self.listener = Listener("metrics", _HttpConn, host=host, port=port, owner=self,
                                 max_connections=max_connections,
                                 idle_timeout_s=idle_timeout_s, stats=stats)
        self._executor: ThreadPoolExecutor | None = None
        self._inflight: dict[Key, asyncio.Future[Page]] = {}
        self._pages: dict[Key, tuple[Page, float]] = {}  # page, loop time it serves until
        self.renders = 0
        self.render_s = 0.0  # time the last rendering took

    @property
    def port(self) -> int:
        return self.listener.port

    async def open(self) -> None:
        await self.listener.open()

    async def start(self) -> None:
        if self._executor is None:
            self._executor = ThreadPoolExecutor(1, thread_name_prefix="metrics")
        await self.listener.start()

    async def stop(self) -> None:
        await self.listener.stop()
        executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=False, cancel_futures=True)

    def page(self, accept: str, gz: bool, names: tuple[str, ...]) -> asyncio.Future[Page]:
        """The rendered exposition: a fresh enough page of the same kind, the rendering under
        way, or a new one. NotAcceptable for an ``Accept`` header it cannot use."""
        encoder, ctype = negotiate(accept)
        key = (ctype, gz, names)
        loop = asyncio.get_running_loop()
        now = loop.time()
        cached = self._pages.get(key)
        if cached is not None and now < cached[1]:
            done: asyncio.Future[Page] = loop.create_future()
            done.set_result(cached[0])
            return done
        running = self._inflight.get(key)
        if running is not None:
            return running
        assert self._executor is not None

        store = self.store_series() if self.store_series is not None else None
        openmetrics = ctype.startswith("application/openmetrics-text")

        def render() -> tuple[Page, float]:
            t0 = time.perf_counter()
            if names:
                body = encoder(self.registry.restricted_registry(names))
            elif store is not None:
                body = store.page(self.registry, encoder, openmetrics)
            else:
                body = encoder(self.registry)
            page = (200, ctype, gzip.compress(body, 5) if gz else body, gz)
            return page, time.perf_counter() - t0

        rendering = loop.run_in_executor(self._executor, render)
        future: asyncio.Future[Page] = loop.create_future()
        self.renders += 1
        self._inflight[key] = future

        def finished(f: asyncio.Future[tuple[Page, float]]) -> None:
            self._inflight.pop(key, None)
            if f.cancelled():
                future.cancel()
                return
            exc = f.exception()
            if exc is not None:  # every scrape waiting on it answers 500; logged once
                self.listener.failed("render", exc)
                future.set_exception(exc)
                return
            page, took = f.result()
            self.render_s = took
            end = loop.time()
            self._pages = {k: v for k, v in self._pages.items() if v[1] > end}
            self._pages[key] = (page, end + RENDER_REST * took)
            future.set_result(page)

        rendering.add_done_callback(finished)
        return future
