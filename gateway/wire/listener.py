"""TCP servers that bound their cost: a connection limit, an idle timeout, no thread per
connection (asyncio protocols on the event loop). The Modbus result server and the simulated
PLC (:mod:`gateway.wire.registers`) and the metrics server
(:mod:`gateway.outputs.prometheus.http`) are built on :class:`Listener`.

* **Limit**: at most ``max_connections`` at once. A connection beyond it closes the one that
  matters least: a connection that never completed a request before one that did, the one
  idle longest first; one in the middle of a request is never closed. So a crowd of
  half-open connections cannot lock out a client that polls.
* **Idle timeout**: a connection with no byte received for ``idle_timeout_s`` is closed
  (a half-open or trickling connection costs at most that long).
* **Garbage**: a protocol closes a connection that sends what it cannot parse
  (:meth:`Conn.drop` with reason ``protocol``).
* **Writes**: a client that does not read its answers stops being read (asyncio flow
  control), so its answers cannot pile up in memory.

:class:`ListenerStats` counts accepted connections and those the server closed, by reason;
the metrics output publishes them (``stiction_server_connections*``).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import os
import socket
import time
from collections.abc import Callable
from typing import Any

__all__ = ["CLOSE_REASONS", "REQUESTS_PER_TURN", "Conn", "Listener", "ListenerStats"]

CLOSE_REASONS = ("limit", "idle", "protocol")
"""Why the server closed a connection: over the connection limit, idle too long, garbage."""
WRITE_HIGH_WATER = 64 * 1024  # bytes of answers queued for a client before it is not read
BACKLOG = 1024  # connections the kernel may queue for accepting: a burst is accepted (and
# the least useful closed) rather than left to retry its SYN seconds later
ACCEPT_BATCH = 16  # connections accepted per wake-up of the event loop
REQUESTS_PER_TURN = 64  # requests one connection has answered before others get a turn


@dataclasses.dataclass
class ListenerStats:
    """What a listener did so far (plain numbers, read from any thread)."""

    open: int = 0
    accepted: int = 0
    closed: dict[str, int] = dataclasses.field(
        default_factory=lambda: dict.fromkeys(CLOSE_REASONS, 0))


class Conn(asyncio.Protocol):
    """A connection served by a :class:`Listener`. Received bytes go to ``buffer``, then
    :meth:`handle` (a subclass's) is called: it takes what it can from the buffer, calls
    :meth:`begin`/:meth:`served` around a request and :meth:`drop` on garbage; after
    :data:`REQUESTS_PER_TURN` requests it returns :meth:`later` (a client that pipelines
    thousands of requests does not hold the event loop). The server it belongs to is
    ``listener.owner``."""

    def __init__(self, listener: Listener) -> None:
        self.listener = listener
        self.buffer = bytearray()
        self.transport: asyncio.Transport | None = None
        self.last = listener.clock()
        self.useful = False  # a complete request was answered on it
        self.busy = False  # a request is being answered: never evicted
        self.closed = False
        self._held: set[str] = set()  # why reading is paused: "write", "turn"

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        transport.set_write_buffer_limits(high=WRITE_HIGH_WATER)
        self.listener.admit(self)

    def connection_lost(self, exc: Exception | None) -> None:
        self.closed = True
        self.listener.forget(self)

    def _hold(self, why: str) -> None:
        self._held.add(why)
        if self.transport is not None and not self.closed:
            self.transport.pause_reading()

    def _release(self, why: str) -> None:
        self._held.discard(why)
        if not self._held and self.transport is not None and not self.closed:
            self.transport.resume_reading()

    def pause_writing(self) -> None:  # the client does not read: stop reading it
        self._hold("write")

    def resume_writing(self) -> None:
        self._release("write")

    def later(self) -> None:
        """Go on with the buffer on the event loop's next turn (reading paused until)."""
        if "turn" in self._held:
            return
        self._hold("turn")

        def go_on() -> None:
            self._held.discard("turn")
            if not self.closed:
                self.handle()
            if "turn" not in self._held:
                self._release("turn")

        asyncio.get_running_loop().call_soon(go_on)

    def data_received(self, data: bytes) -> None:
        self.last = self.listener.clock()
        self.buffer += data
        self.handle()

    def handle(self) -> None:
        """Take requests from ``buffer`` (subclasses)."""
        raise NotImplementedError

    def begin(self) -> None:
        self.busy = True

    def served(self) -> None:
        self.busy = False
        self.useful = True
        self.last = self.listener.clock()

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
                 stats: ListenerStats | None = None) -> None:
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
        self.conns: set[Conn] = set()
        self.stats = stats if stats is not None else ListenerStats()
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
        for conn in list(self.conns):
            self._remove(conn)
            if conn.transport is not None:
                conn.transport.abort()
        if server is not None:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(server.wait_closed(), 1.0)

    # ------------------------------------------------------------------ connections

    def admit(self, conn: Conn) -> None:
        self.stats.accepted += 1
        if len(self.conns) >= self.max_connections:
            victim = min((c for c in self.conns if not c.busy),
                         key=lambda c: (c.useful, c.last), default=None)
            if victim is None:  # every slot is answering a request: refuse the newcomer
                conn.drop("limit")
                return
            self._remove(victim)
            victim.drop("limit")
        self.conns.add(conn)
        self.stats.open += 1

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
