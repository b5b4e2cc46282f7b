"""Issue 31 (a third round of attacks), findings 4, 5 and 6 (the lateness of ticks). Each
test failed on main the day the issue was filed (3dfa8c7).

4. a device that went down while flagged behind schedule kept
   ``stiction_device_behind_schedule 1`` for the whole outage: two alerts for one fault;
5. a SCADA client reconnecting under a reconnect storm lost reads: the storm's newcomers
   closed its connection before its first request (a client that has just connected was
   taken for half-open);
6. the tests' measure of tick lateness took each tick for the nearest slot of the schedule:
   a tick up to half a period late read as early, so the bounds could not fail.

Finding 1 (a wall clock stepped back across a restart): tests/test_hostile_clock.py and
tests/e2e/test_clock_step.py; finding 3 (OPC UA): tests/e2e/test_opcua_refusals.py.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop, wiggle
from reliability_helpers import lateness

from bench.attacks._attacks import read_frame
from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.wire.listener import JUST_CONNECTED_S, Conn, Listener
from gateway.wire.registers import RegisterServer

# ------------------------------------------------------------------ 4. one fault, one alert


def test_a_device_that_goes_down_is_no_longer_behind_schedule(
        caplog: pytest.LogCaptureFixture) -> None:
    """A device flagged behind schedule goes down: the flag (and its gauge) clears with the
    outage, so StictionDeviceDown is the one alert (main: stiction_device_behind_schedule
    stayed 1 for the whole outage); back up, its schedule is judged afresh: on time, it is
    not flagged again."""
    caplog.set_level(logging.WARNING, logger="gateway")
    h = Harness(parse_config(mconfig(
        [memory_device("plc", wiggle(50, 2), poll_interval_s=1.0, repeat=True)],
        [mloop("A", "plc", 0, 0, window_s=60.0)]), "<behind>"))
    p = h.poller("plc")
    for t in range(3):  # three ticks missed in a row: behind
        p.report.schedule(1, 0.0, float(t), up=True)
    assert h.metric("stiction_device_behind_schedule", device="plc") == 1

    def gauges() -> tuple[float | None, float | None]:
        return (h.metric("stiction_device_up", device="plc"),
                h.metric("stiction_device_behind_schedule", device="plc"))

    out: dict[str, Any] = {}

    async def go() -> None:
        h.source("plc").down = "connect"
        await h.tick(20)
        out["down"] = gauges()
        h.source("plc").down = None
        await h.tick(30)
        out["up"] = gauges()

    asyncio.run(go())
    assert out["down"] == (0.0, 0.0)
    assert out["up"] == (1.0, 0.0)
    assert not p.report.lag.behind


# ------------------------------------------------------------------ 5. reconnect storm


def test_a_client_that_just_connected_is_not_yet_half_open() -> None:
    """The policy (fake clock, no sockets): the last connections to arrive (an eighth of
    the slots), younger than JUST_CONNECTED_S and waiting for their first answer, are not
    closed for a newcomer while another can be: the busiest goes (main: the one that just
    connected). Once older it is half-open and the first to go; a flood of half-open
    connections loses its oldest first, never a connection that completed requests."""
    now = [100.0]
    listener = Listener("t", Conn, host="127.0.0.1", port=0, max_connections=16,
                        idle_timeout_s=60, clock=lambda: now[0])
    quiet, busy = Conn(listener), Conn(listener)
    for k in range(200):
        now[0] = 100.0 + k * 0.05
        busy.served(1)
        if k % 20 == 0:
            quiet.served(1)
    just = Conn(listener)  # connected at now, its request not answered yet
    listener.conns = {quiet, busy, just}
    assert listener.victim(now[0]) == (busy, "busiest")  # main: (just, "limit")
    assert listener.victim(now[0] + JUST_CONNECTED_S / 2) == (busy, "busiest")
    assert listener.victim(now[0] + JUST_CONNECTED_S) == (just, "limit")  # half-open now
    flood = []
    for _ in range(13):  # a flood of half-open connections, all of them young
        now[0] += 0.001
        flood.append(Conn(listener))
    listener.conns = {quiet, busy, just, *flood}
    victims = []
    while listener.conns - {quiet, busy}:
        victim, reason = listener.victim(now[0])
        assert victim is not None and reason == "limit", (victim, reason)
        victims.append(victim)
        listener.conns.discard(victim)
        if len(listener.conns) == 4:  # the two kept: the newest, in their first 0.5 s
            assert listener.conns - {quiet, busy} == set(flood[-2:])
            break
    assert victims == [just, *flood[:-2]]  # the oldest first


def test_a_scada_client_reconnecting_in_a_reconnect_storm_gets_every_read() -> None:
    """8 slots, 7 clients reading 20 times a (fake) second; a SCADA client opens a new
    connection for each of its 20 reads, and before it sends its request three of the
    storm's clients reconnect. Every SCADA read is answered (main: the first newcomer
    closed the SCADA connection, as the one connection that had not completed a request:
    none answered); the storm's newcomers close the busiest instead."""
    now = [0.0]

    async def go() -> dict[str, Any]:
        image = _image()
        server = RegisterServer({"holding": image, "input": image}, host="127.0.0.1", port=0,
                                max_connections=8)
        server.listener.clock = lambda: now[0]
        await server.start()

        async def client() -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
            return await asyncio.open_connection("127.0.0.1", server.port)

        async def read(c: tuple[asyncio.StreamReader, asyncio.StreamWriter]) -> bool:
            reader, writer = c
            try:
                writer.write(read_frame(1, 0, 20))
                return len(await asyncio.wait_for(reader.readexactly(49), 2)) == 49
            except (OSError, asyncio.IncompleteReadError, TimeoutError):
                return False

        busy = [await client() for _ in range(7)]
        answers, storm = [], []
        try:
            for _second in range(20):
                for _step in range(20):
                    now[0] += 0.05
                    for c in busy:
                        await read(c)
                scada = await client()  # a new connection for each read
                await asyncio.sleep(0.01)  # admitted
                for _ in range(3):  # the storm reconnects before SCADA's request
                    newcomer = await client()
                    storm.append(await read(newcomer))
                    busy.append(newcomer)
                answers.append(await read(scada))
                scada[1].close()
        finally:
            for _r, w in busy:
                w.close()
            stats = server.listener.stats
            await server.stop()
        return {"answers": answers, "storm": storm, "closed": dict(stats.closed)}

    out = asyncio.run(asyncio.wait_for(go(), 50))
    assert out["answers"] == [True] * 20, out["answers"]
    assert out["closed"]["busiest"] >= 60 and out["closed"]["limit"] == 0, out["closed"]


def _image() -> Any:
    return np.arange(200, dtype=np.uint16)


# ------------------------------------------------------------------ 6. tick lateness


def test_the_lateness_of_ticks_is_measured_on_the_schedule_tick_after_tick() -> None:
    """Ticks every 100 ms with 1-8 ms of jitter: on time. One 70 ms late (the red team's
    blocked poller, bound 50 ms): main's measure read it 30 ms early and the test passed;
    here it is a missed tick the poller did not count, and every tick after it reads a
    period late. A tick really missed is counted where it was, the others on time."""
    rng = np.random.default_rng(3)
    grid = 100.0 + 0.1 * np.arange(40)
    jitter = rng.uniform(0.001, 0.008, len(grid))
    late, missed = lateness(list(grid + jitter), 0.1)
    assert late.max() < 0.01 and missed.sum() == 0
    blocked = grid + jitter
    blocked[20] += 0.07
    late, missed = lateness(list(blocked), 0.1)
    assert missed.sum() == 1 or late.max() >= 0.05  # seen, either way
    assert late.max() >= 0.09  # the ticks after it: a period off
    skipped = np.delete(grid + jitter, 20)  # tick 20 missed (the poller counts it)
    late, missed = lateness(list(skipped), 0.1)
    assert missed.tolist() == [0] * 20 + [1] + [0] * 18 and late.max() < 0.01
