"""The /metrics HTTP server: asyncio connections on a bounded
:class:`~gateway.wire.listener.Listener` (``metrics.max_connections``,
``metrics.idle_timeout_s``), not a thread per connection.

``GET`` (or ``HEAD``) of ``/metrics`` or ``/`` answers the registry's exposition: the
``Accept`` header picks OpenMetrics or the text format, ``name[]`` query parameters restrict
the series (as prometheus_client's own server does), gzip when accepted. Rendering runs in
one worker thread (the collectors read a snapshot of the store); scrapes that arrive while a
rendering is under way share it, so a crowd of scrapers costs one rendering at a time.
Other paths get 404, other methods 405, a request with a body or a malformed request 400,
headers over 8 KiB 431; the last three close the connection.
"""

from __future__ import annotations

import asyncio
import gzip
from concurrent.futures import ThreadPoolExecutor
from urllib.parse import parse_qs

from prometheus_client import CollectorRegistry
from prometheus_client.exposition import choose_encoder

from ...wire.listener import Conn, Listener, ListenerStats

__all__ = ["MAX_HEAD_BYTES", "MetricsServer"]

MAX_HEAD_BYTES = 8192
_REASONS = {200: "OK", 400: "Bad Request", 404: "Not Found", 405: "Method Not Allowed",
            431: "Request Header Fields Too Large", 500: "Internal Server Error"}
Page = tuple[int, str, bytes, bool]  # status, content type, body, gzipped


class _HttpConn(Conn):
    """One client connection: requests in, one at a time, answers out."""

    def handle(self) -> None:
        if not self.busy:
            self._next()
        elif len(self.buffer) > 2 * MAX_HEAD_BYTES:  # pipelining far ahead of the answers
            self.drop("protocol")

    def _next(self) -> None:
        buf = self.buffer
        end = buf.find(b"\r\n\r\n")
        if end < 0:
            if len(buf) > MAX_HEAD_BYTES:
                self._reply(431, b"request headers too large\n", keep=False)
            return
        if end > MAX_HEAD_BYTES:
            self._reply(431, b"request headers too large\n", keep=False)
            return
        lines = bytes(buf[:end]).decode("latin-1").split("\r\n")
        del buf[:end + 4]
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
        path, _, query = target.partition("?")
        if path not in ("/", "/metrics"):
            self._reply(404, b"not found: try /metrics\n", keep=keep, head=method == "HEAD")
            return
        self.begin()
        names = tuple(sorted(parse_qs(query).get("name[]", [])))
        gz = "gzip" in headers.get("accept-encoding", "").lower()
        server: MetricsServer = self.listener.owner
        task = asyncio.ensure_future(server.page(headers.get("accept", ""), gz, names))
        task.add_done_callback(lambda t: self._rendered(t, keep, method == "HEAD"))

    def _rendered(self, task: asyncio.Future[Page], keep: bool, head: bool) -> None:
        if self.closed:
            return
        if task.cancelled() or task.exception() is not None:
            self._reply(500, b"the metrics could not be rendered\n", keep=False)
            return
        status, ctype, body, gz = task.result()
        self._reply(status, body, keep=keep, head=head, ctype=ctype, gz=gz)
        if keep and not self.closed:
            self._next()

    def _reply(self, status: int, body: bytes, *, keep: bool, head: bool = False,
               ctype: str = "text/plain; charset=utf-8", gz: bool = False) -> None:
        lines = [f"HTTP/1.1 {status} {_REASONS.get(status, '')}", f"Content-Type: {ctype}",
                 f"Content-Length: {len(body)}",
                 f"Connection: {'keep-alive' if keep else 'close'}"]
        if gz:
            lines.append("Content-Encoding: gzip")
        self.write(("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + (b"" if head else body))
        self.served()
        if not keep and self.transport is not None:
            if status >= 400:
                self.listener.stats.closed["protocol"] += 1
            self.closed = True
            self.transport.close()  # after the answer is sent


class MetricsServer:
    """Serves ``registry`` over HTTP on ``host:port`` (see the module docstring)."""

    def __init__(self, registry: CollectorRegistry, host: str, port: int, *,
                 max_connections: int, idle_timeout_s: float,
                 stats: ListenerStats | None = None) -> None:
        self.registry = registry
        self.listener = Listener("metrics", _HttpConn, host=host, port=port, owner=self,
                                 max_connections=max_connections,
                                 idle_timeout_s=idle_timeout_s, stats=stats)
        self._executor: ThreadPoolExecutor | None = None
        self._inflight: dict[tuple[str, bool, tuple[str, ...]], asyncio.Future[Page]] = {}
        self.renders = 0

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
        """The rendered exposition; requests for the same rendering share one."""
        encoder, ctype = choose_encoder(accept)
        key = (ctype, gz, names)
        running = self._inflight.get(key)
        if running is not None:
            return running
        loop = asyncio.get_running_loop()
        assert self._executor is not None

        def render() -> Page:
            registry = self.registry.restricted_registry(names) if names else self.registry
            body = encoder(registry)
            return 200, ctype, gzip.compress(body, 5) if gz else body, gz

        future = asyncio.ensure_future(loop.run_in_executor(self._executor, render))
        self.renders += 1
        self._inflight[key] = future
        future.add_done_callback(lambda _f: self._inflight.pop(key, None))
        return future
