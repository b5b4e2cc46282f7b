"""TCP servers that bound their cost and never hold the event loop: a connection limit, an
idle timeout, bounded memory per connection and a budget of requests per event-loop turn
(asyncio protocols, no thread per connection). The Modbus result server and the simulated
PLC (:mod:`gateway.wire.registers`) and the metrics server
(:mod:`gateway.outputs.prometheus.http`) are built on :class:`Listener`.

* **Turns**: a connection's requests are not answered where its bytes arrive; the listener
  answers at most :data:`TURN_REQUESTS` requests per turn of the event loop, all its
  connections together, and at most :data:`CONN_TURN_REQUESTS` of one connection before the
  next ready one (round robin), then yields. Whatever clients send, a poll waiting for its
  PLC's answer waits for at most one such turn per round trip (the pollers share this
  event loop: docs/architecture.md, "Polling comes first").
* **Memory**: at most ``Conn.in_limit`` bytes of requests are held per connection (reading
  stops beyond; the kernel's buffers and then TCP flow control hold the rest); while more
  than :data:`WRITE_HIGH_WATER` bytes of answers wait for a client to read them, none of its
  requests is answered nor read (one answer may exceed it: a /metrics page is queued whole).
* **Limit**: at most ``max_connections`` at once. A newcomer beyond it closes the connection
  that costs the most (:meth:`Listener.victim`): first one that never completed a request
  (half-open, the longest idle first: reason ``limit``), then one whose answers are queued
  unread (most bytes queued, then the oldest pending: ``unread``), then the busiest
  (highest recent request rate: ``busiest``). The last few to connect (an eighth of the
  slots) are not yet half-open for :data:`JUST_CONNECTED_S`: a reconnect storm closes its
  busiest, never a client's new connection before its first request (a flood of half-open
  ones still loses its oldest first). A quiet client is the last to go.
* **Idle timeout**: a connection with no byte received for ``idle_timeout_s`` is closed,
  unless an answer is being prepared for it (a half-open or trickling connection costs at
  most that long).
* **Garbage and faults**: a protocol closes a connection that sends what it cannot parse
  (:meth:`Conn.drop`, reason ``protocol``). An exception while answering is logged through
  :func:`report` (the log's rate limit keys it by place and type, never by its text),
  counted in ``stats.errors`` and closes that connection (reason ``error``); it never
  reaches the event loop.

:class:`ListenerStats` counts accepted connections, those the server closed by reason and
the errors; the metrics output publishes them (``stiction_server_*``).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import dataclasses
import logging
import math
import os
import socket
import time
from collections.abc import Callable
from typing import Any

__all__ = ["CLOSE_REASONS", "CONN_TURN_REQUESTS", "ERROR_STAGES", "JUST_CONNECTED_S",
           "TURN_REQUESTS", "WRITE_HIGH_WATER", "Conn", "Listener", "ListenerStats", "report"]

log = logging.getLogger("gateway.server")

CLOSE_REASONS = ("limit", "unread", "busiest", "idle", "protocol", "error")
"""Why the server closed a connection: for a newcomer over the connection limit (one that
never completed a request; one whose answers were not read; the busiest), idle too long,
garbage, an error while answering."""
ERROR_STAGES = ("request", "render")
"""Where a serving path failed: answering a request, rendering the metrics page."""
WRITE_HIGH_WATER = 64 * 1024  # bytes of answers queued for a client before it is not served
BACKLOG = 1024  # connections the kernel may queue for accepting: a burst is accepted (and
# the least useful closed) rather than left to retry its SYN seconds later
ACCEPT_BATCH = 16  # connections accepted per wake-up of the event loop
TURN_REQUESTS = 32  # requests a listener answers per turn of the event loop, all clients
CONN_TURN_REQUESTS = 4  # ... of which one client at most before the next one's turn
RATE_TAU_S = 10.0  # time constant of a connection's request rate (eviction)
RATE_MIN_AGE_S = 1.0  # a young connection's rate is counted over at least this long
JUST_CONNECTED_S = 0.5  # a client's first request may take this long after it connects


def report(server: str, place: str, exc: BaseException) -> None:
    """Log an unexpected exception of a serving path once, with its traceback. The first
    argument, the cause (server, place, exception type), is what the log's rate limit
    (:mod:`gateway.runtime.logs`) counts by; the text, which may hold a client's bytes or
    addresses, comes second and is cut short."""
    text = " ".join(str(exc).split())[:200]
    log.error("%s: %s", f"{server} server, {place}: {type(exc).__name__}", text, exc_info=exc)


@dataclasses.dataclass
class ListenerStats:
    """What a listener did so far (plain numbers, read from any thread)."""

    open: int = 0
    accepted: int = 0
    closed: dict[str, int] = dataclasses.field(
        default_factory=lambda: dict.fromkeys(CLOSE_REASONS, 0))
    errors: dict[str, int] = dataclasses.field(
        default_factory=lambda: dict.fromkeys(ERROR_STAGES, 0))


class Conn(asyncio.BufferedProtocol):
    """A connection served by a :class:`Listener`. Received bytes go to ``buffer`` (at most
    ``in_limit``); a subclass says when a request is complete (:meth:`ready`) and answers up
    to ``n`` of them when the listener gives it a turn (:meth:`serve`), calling
    :meth:`served` after writing their answers. ``busy`` marks an answer prepared elsewhere
    (a rendering): no request of the connection is served meanwhile. The server it belongs
    to is ``listener.owner``."""

    in_limit = 4096

    def __init__(self, listener: Listener) -> None:
        self.listener = listener
        self.buffer = bytearray()
        self.transport: asyncio.Transport | None = None
        now = listener.clock()
        self.born = self.last = now
        self.useful = False  # a complete request was answered on it
        self.busy = False  # an answer is being prepared: not served, not swept
        self.closed = False
        self.pending_since: float | None = None  # the oldest request not answered yet
        self._held: set[str] = set()  # why reading is paused: "input", "write"
        self._load, self._load_t = 0.0, now  # decayed count of answered requests

    # ------------------------------------------------------------------ asyncio's side

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        transport.set_write_buffer_limits(high=WRITE_HIGH_WATER)
        self.listener.admit(self)

    def connection_lost(self, exc: Exception | None) -> None:
        self.closed = True
        self.listener.forget(self)

    def get_buffer(self, sizehint: int) -> memoryview:
        return self.listener.chunk[:max(256, self.in_limit - len(self.buffer))]

    def buffer_updated(self, nbytes: int) -> None:
        now = self.listener.clock()
        self.last = now
        if self.pending_since is None:
            self.pending_since = now
        self.buffer += self.listener.chunk[:nbytes]
        if len(self.buffer) >= self.in_limit:
            self._hold("input")
        self.listener.wake(self)

    def pause_writing(self) -> None:  # the client does not read: stop serving it
        self._hold("write")

    def resume_writing(self) -> None:
        self._release("write")
        self.listener.wake(self)

    def _hold(self, why: str) -> None:
        self._held.add(why)
        if self.transport is not None and not self.closed:
            self.transport.pause_reading()

    def _release(self, why: str) -> None:
        if why not in self._held:
            return
        self._held.discard(why)
        if not self._held and self.transport is not None and not self.closed:
            self.transport.resume_reading()

    # ------------------------------------------------------------------ the protocol's side

    def ready(self) -> bool:
        """Whether ``buffer`` holds a request to answer (or garbage to refuse)."""
        raise NotImplementedError

    def serve(self, n: int) -> int:
        """Answer up to ``n`` requests from ``buffer``; returns how many were taken."""
        raise NotImplementedError

    @property
    def blocked(self) -> bool:
        """Not to be served now: its answers are not read, or one is being prepared."""
        return self.busy or "write" in self._held

    def turn(self, n: int) -> int:
        """:meth:`serve` for the listener; an exception closes this connection only."""
        try:
            used = self.serve(n)
        except Exception as exc:  # a bug must cost one connection, never the event loop
            self.listener.failed("request", exc)
            self.drop("error")
            return 1
        if "input" in self._held and len(self.buffer) < self.in_limit:
            self._release("input")
        if not self.buffer and not self.busy:
            self.pending_since = None
        return used

    def served(self, k: int = 1) -> None:
        """``k`` requests were answered (their answers written)."""
        now = self.listener.clock()
        self.useful = True
        self.last = now
        self._load = self._load * math.exp((self._load_t - now) / RATE_TAU_S) + k
        self._load_t = now

    def rate(self, now: float) -> float:
        """Requests answered per second lately (decayed over :data:`RATE_TAU_S`, a young
        connection's counted over at least :data:`RATE_MIN_AGE_S`)."""
        load = self._load * math.exp((self._load_t - now) / RATE_TAU_S)
        span = RATE_TAU_S * -math.expm1((self.born - now) / RATE_TAU_S)
        return load / max(span, RATE_MIN_AGE_S)

    def queued(self) -> int:
        """Bytes of answers written but not yet taken by the client (asyncio's buffer)."""
        if self.transport is None or self.closed:
            return 0
        return int(self.transport.get_write_buffer_size())

    def write(self, data: bytes) -> None:
        if self.transport is not None and not self.closed:
            self.transport.write(data)

    def drop(self, reason: str) -> None:
        """Close now (unsent answers are discarded), counted under ``reason``."""
        if self.closed:
            return
        self.closed = True
        self.listener.stats.closed[reason] += 1
        if self.transport is not None:
            self.transport.abort()


class Listener:
    """One listening address served by ``factory(listener) -> Conn`` protocols.

    :meth:`open` binds (raising OSError if the address is taken) without serving yet, so a
    reload can bind every new listener before it swaps; :meth:`serve` starts accepting;
    :meth:`start` does both; :meth:`stop` closes the socket and every connection. ``stats``
    may be shared with the listener this one replaces, so that the counts go on."""

    def __init__(self, name: str, factory: Callable[[Listener], Conn], *, host: str,
                 port: int, max_connections: int, idle_timeout_s: float, owner: Any = None,
                 clock: Callable[[], float] = time.monotonic,
                 stats: ListenerStats | None = None, turn_requests: int = TURN_REQUESTS,
                 conn_turn_requests: int = CONN_TURN_REQUESTS) -> None:
        if max_connections < 1:
            raise ValueError(f"`max_connections` must be >= 1, was {max_connections}")
        if idle_timeout_s <= 0:
            raise ValueError(f"`idle_timeout_s` must be > 0, was {idle_timeout_s}")
        self.name = name
        self.factory = factory
        self.owner = owner  # the server the connections answer for
        self.host, self.port = host, port
        self.max_connections = max_connections
        self.idle_timeout_s = idle_timeout_s
        self.clock = clock
        self.turn_requests, self.conn_turn_requests = turn_requests, conn_turn_requests
        self.conns: set[Conn] = set()
        self.stats = stats if stats is not None else ListenerStats()
        self.chunk = memoryview(bytearray(64 * 1024))  # every connection reads into it
        self._ready: collections.deque[Conn] = collections.deque()  # connections to serve
        self._queued: set[Conn] = set()
        self._turn: asyncio.Handle | None = None
        self._server: asyncio.Server | None = None
        self._sweeper: asyncio.Task[None] | None = None

    @property
    def serving(self) -> bool:
        return self._sweeper is not None

    async def open(self) -> None:
        """Bind the address (not accepting yet); OSError if it is in use."""
        if self._server is not None:
            return
        loop = asyncio.get_running_loop()
        # asyncio accepts up to `backlog` connections per wake-up before any of them is
        # admitted (each an open file): a small batch keeps the descriptors in flight few,
        # while the kernel's queue (set in serve) stays long
        self._server = await loop.create_server(
            lambda: self.factory(self), self.host or None, self.port, reuse_address=True,
            backlog=ACCEPT_BATCH, start_serving=False)
        self.port = int(self._server.sockets[0].getsockname()[1])

    async def serve(self) -> None:
        """Start accepting connections (after :meth:`open`)."""
        if self._server is None:
            await self.open()
        assert self._server is not None
        await self._server.start_serving()  # listens with the batch size as its backlog
        for sock in self._server.sockets:
            with socket.socket(fileno=os.dup(sock.fileno())) as same:
                same.listen(BACKLOG)
        if self._sweeper is None:
            self._sweeper = asyncio.create_task(self._sweep(), name=f"{self.name} idle")

    async def start(self) -> None:
        await self.open()
        await self.serve()

    async def stop(self) -> None:
        server, self._server = self._server, None
        sweeper, self._sweeper = self._sweeper, None
        if sweeper is not None:
            sweeper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sweeper
        if server is not None:
            server.close()
        if self._turn is not None:
            self._turn.cancel()
            self._turn = None
        self._ready.clear()
        self._queued.clear()
        for conn in list(self.conns):
            self._remove(conn)
            conn.closed = True
            if conn.transport is not None:
                conn.transport.abort()
        if server is not None:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(server.wait_closed(), 1.0)

    # ------------------------------------------------------------------ turns

    def wake(self, conn: Conn) -> None:
        """Serve ``conn`` at the next turn if it holds a request it may be answered."""
        if conn in self._queued or conn.closed or conn.blocked or not conn.ready():
            return
        self._queued.add(conn)
        self._ready.append(conn)
        if self._turn is None:
            self._turn = asyncio.get_running_loop().call_soon(self._serve_turn)

    def _serve_turn(self) -> None:
        """One turn: at most ``turn_requests`` requests, ``conn_turn_requests`` per
        connection, round robin; what is left waits for the next turn of the event loop
        (the callbacks that became ready meanwhile, a poll's answer among them, run
        first)."""
        self._turn = None
        budget = self.turn_requests
        while budget > 0 and self._ready:
            conn = self._ready.popleft()
            self._queued.discard(conn)
            if conn.closed or conn.blocked or not conn.ready():
                continue
            budget -= max(1, conn.turn(min(self.conn_turn_requests, budget)))
            if not conn.closed and not conn.blocked and conn.ready():
                self._queued.add(conn)
                self._ready.append(conn)
        if self._ready:
            self._turn = asyncio.get_running_loop().call_soon(self._serve_turn)

    def failed(self, stage: str, exc: BaseException) -> None:
        """An exception on a serving path: counted and logged (rate-limited by cause)."""
        self.stats.errors[stage] = self.stats.errors.get(stage, 0) + 1
        report(self.name, stage, exc)

    # ------------------------------------------------------------------ connections

    def admit(self, conn: Conn) -> None:
        self.stats.accepted += 1
        if len(self.conns) >= self.max_connections:
            victim, reason = self.victim(self.clock())
            if victim is None:
                conn.drop("limit")
                return
            self._remove(victim)
            victim.drop(reason)
        self.conns.add(conn)
        self.stats.open += 1

    def victim(self, now: float) -> tuple[Conn | None, str]:
        """The connection a newcomer over the limit closes, and why (see the module)."""
        never = [c for c in self.conns if not c.useful and not c.busy]
        young = sorted((c for c in never if now - c.born < JUST_CONNECTED_S), key=lambda c: c.born)
        kept = set(young[-max(1, self.max_connections // 8):])  # not yet half-open
        half_open = [c for c in never if c not in kept]
        if half_open:
            return min(half_open, key=lambda c: c.last), "limit"
        if unread := [c for c in self.conns if c.queued() >= WRITE_HIGH_WATER]:
            return max(unread, key=lambda c: (c.queued(), now - (c.pending_since or now))), \
                "unread"
        if rest := [c for c in self.conns if c not in kept]:
            return max(rest, key=lambda c: (c.rate(now), now - c.last)), "busiest"
        return (min(kept, key=lambda c: c.born), "limit") if kept else (None, "limit")

    def forget(self, conn: Conn) -> None:
        self._remove(conn)

    def _remove(self, conn: Conn) -> None:
        if conn in self.conns:
            self.conns.discard(conn)
            self.stats.open -= 1

    def sweep(self, now: float) -> int:
        """Close every connection idle for over ``idle_timeout_s`` at ``now``; how many."""
        idle = [c for c in self.conns if not c.busy and now - c.last > self.idle_timeout_s]
        for c in idle:
            self._remove(c)
            c.drop("idle")
        return len(idle)

    async def _sweep(self) -> None:
        step = min(1.0, self.idle_timeout_s / 4)
        while True:
            await asyncio.sleep(step)
            self.sweep(self.clock())
