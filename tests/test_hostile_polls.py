"""Issue 22: every missed or late tick is visible, and a PLC's answer is data only when it
is the answer asked for. Each test failed on main the day the issue was filed (cc81e67).

Finding 1's other half: polls starved to 38 % of their rate left ``stiction_device_up`` at
1, no log line, no stale flag, no metric, and the gap rows of the missed ticks shared one
timestamp. Smaller findings: a PLC answering function code 4 for 3 was good data; a byte
count beyond the frame raised on the event loop (a traceback per answer) and counted as
``kind=timeout``; random register garbage with no ``range`` published a PV of -2.9e38.
"""

from __future__ import annotations

import asyncio
import logging
import struct
import time
from typing import Any

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop, wiggle
from prometheus_client import CollectorRegistry

from gateway.config import parse_config
from gateway.core.points import PointSpec, Quality
from gateway.errors import DeviceError
from gateway.inputs.memory import memory_device
from gateway.inputs.modbus.client import ModbusInput
from gateway.inputs.modbus.config import ModbusDeviceOptions, ModbusPoint
from gateway.outputs.prometheus import GatewayMetrics
from gateway.runtime.poller import Clocks
from gateway.runtime.reload import build_runtime

PERIOD = 0.05


def test_missed_ticks_are_counted_stamped_at_their_own_times_and_flag_the_device(
        caplog: pytest.LogCaptureFixture) -> None:
    """A read that takes 4.25 periods (its clock jumps, so the count is exact): the three
    ticks it missed are gap rows one period apart (main: one timestamp for all three), the
    loops went stale meanwhile, stiction_poll_missed_ticks_total counts them,
    stiction_poll_lateness_seconds has every tick, and the device is flagged behind
    schedule (metric and one log line)."""
    caplog.set_level(logging.WARNING, logger="gateway")
    cfg = parse_config(mconfig([memory_device("plc", wiggle(50, 2), poll_interval_s=PERIOD,
                                              repeat=True)],
                               [mloop("A", "plc", 0, 0, window_s=5.0)]), "<test>")
    registry = CollectorRegistry()
    metrics = GatewayMetrics(registry)
    metrics.add_device("plc")
    offset = [0.0]
    out: dict[str, Any] = {}

    async def go() -> None:
        loop = asyncio.get_running_loop()
        rt = build_runtime(cfg, wall=0.0, metrics=metrics,
                           clocks=Clocks(mono=lambda: loop.time() + offset[0],
                                         wall=lambda: time.time() + offset[0]))
        p, store = rt.pollers[0], rt.store
        stale_seen: list[bool] = []
        store.subscribe(lambda i: stale_seen.append(bool(store.stale[i])))
        read = p.source.read

        async def slow_once() -> Any:
            if p.polls == 10:
                offset[0] += 4.25 * PERIOD  # this read took 4.25 periods
            return await read()

        p.source.read = slow_once  # type: ignore[method-assign]
        task = asyncio.create_task(p.run())
        while p.polls < 20:  # noqa: ASYNC110 - a counter
            await asyncio.sleep(PERIOD / 4)
        p.request_stop()
        await task
        out["poller"], out["groups"], out["stale"] = p, rt.groups, stale_seen

    asyncio.run(asyncio.wait_for(go(), 30))
    p = out["poller"]
    t, _op, _pv, q = out["groups"][0].bank.series([0])
    gaps = t[q[0] == Quality.NO_COMM]
    assert p.missed_ticks == 3 and len(gaps) == 3
    np.testing.assert_allclose(np.diff(gaps), PERIOD, atol=1e-5)  # each at its own tick
    assert (np.diff(t) > 0).all()
    assert True in out["stale"]  # no fresh sample for three ticks: stale, then fresh again

    def v(name: str, **labels: str) -> float | None:
        return registry.get_sample_value(name, {"device": "plc", **labels})

    assert v("stiction_poll_missed_ticks_total") == 3
    assert v("stiction_poll_lateness_seconds_count") == p.polls
    assert v("stiction_device_behind_schedule") == 1
    lines = [r.getMessage() for r in caplog.records if "poll_interval_s" in r.getMessage()]
    assert len(lines) == 1 and "3 of the last" in lines[0] and "ticks missed" in lines[0], lines


def test_a_device_is_behind_while_it_misses_a_tenth_of_its_ticks() -> None:
    """The rule of the flag (fake clock): one missed tick is a hiccup (counted, a gap, not
    a device that cannot keep its interval); a tenth of the ticks of the last minute missed
    is; the flag holds until the misses in the window fall under a twentieth."""
    from gateway.core.ticks import Lag  # noqa: PLC0415

    lag = Lag(1.0)
    for t in range(100):  # on time
        assert lag.update(float(t), 0) is None
    assert lag.update(100.0, 1) is None and not lag.behind  # a hiccup
    changes = [lag.update(101.0 + t, 1 if t % 5 == 0 else 0) for t in range(30)]
    assert changes.count(True) == 1 and lag.behind  # one tick in five missed
    t0 = 131.0
    changes = [lag.update(t0 + t, 0) for t in range(60)]
    assert changes.count(False) == 1 and not lag.behind  # caught up within a window
    assert lag.missed == 0
    assert Lag(30.0).window_s == 300.0


# ------------------------------------------------------------------ strict answers


class _Plc:
    """A Modbus server that answers reads of holding registers wrongly, as ``mode`` says:
    ``fc`` with function code 4, ``bytecount`` with a byte count 2 beyond the frame."""

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.server: asyncio.Server | None = None

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                tid, _proto, length, unit = struct.unpack(">HHHB", await reader.readexactly(7))
                fc, _address, count = struct.unpack(">BHH", await reader.readexactly(length - 1))
                data = struct.pack(">ff", 50.0, 20.0)[:2 * count].ljust(2 * count, b"\0")
                body = (bytes([4, 2 * count]) if self.mode == "fc"
                        else bytes([fc, 2 * count + 2])) + data
                writer.write(struct.pack(">HHHB", tid, 0, len(body) + 1, unit) + body)
        except (OSError, asyncio.IncompleteReadError):
            writer.close()

    async def __aenter__(self) -> int:
        self.server = await asyncio.start_server(self._serve, "127.0.0.1", 0)
        return int(self.server.sockets[0].getsockname()[1])

    async def __aexit__(self, *exc: object) -> None:
        assert self.server is not None
        self.server.close()


def _source(port: int) -> ModbusInput:
    points = [PointSpec("A", "op", ModbusPoint(0, "float32")),
              PointSpec("A", "pv", ModbusPoint(2, "float32"))]
    return ModbusInput("plc", ModbusDeviceOptions("127.0.0.1", port), points, timeout_s=1.0)


def test_an_answer_with_another_function_code_is_a_protocol_error_not_data() -> None:
    """Smaller finding: a PLC answering a read of holding registers (3) with function code
    4 was accepted as good data."""
    async def go() -> Any:
        async with _Plc("fc") as port:
            source = _source(port)
            await source.connect()
            try:
                return await source.read()
            finally:
                await source.close()

    result = asyncio.run(asyncio.wait_for(go(), 20))
    assert result.quality.tolist() == [Quality.NO_COMM] * 2
    assert np.isnan(result.values).all()
    assert [e.kind for e in result.errors] == ["protocol"]
    assert "function code 4, not 3" in str(result.errors[0])


def test_a_byte_count_beyond_the_frame_is_a_protocol_error_at_once(
        caplog: pytest.LogCaptureFixture) -> None:
    """Smaller finding: pymodbus raised on the event loop (asyncio logged a traceback per
    answer, with no rate limit) and the read waited for its timeout, counted as
    ``kind=timeout``. It fails at once as ``kind=protocol``; asyncio logs nothing."""
    caplog.set_level(logging.WARNING)

    async def go() -> tuple[DeviceError | None, float]:
        async with _Plc("bytecount") as port:
            source = _source(port)
            await source.connect()
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            try:
                await source.read()
            except DeviceError as exc:
                return exc, loop.time() - t0
            finally:
                await source.close()
        return None, 0.0

    err, took = asyncio.run(asyncio.wait_for(go(), 20))
    assert err is not None and err.kind == "protocol", err
    assert "undecodable answer" in str(err)
    assert took < 1.0  # not its 1 s timeout
    assert not [r for r in caplog.records if r.name == "asyncio"]


def test_register_garbage_is_bad_even_with_no_range() -> None:
    """Smaller finding: random register garbage with no ``range`` set published
    ``stiction_loop_pv -2.9e38``. A magnitude above 1e15 is BAD whatever the config; the
    loop's PV is not published and the poller names the point once."""
    rows = [[50.0, -2.9e38], [50.0, 3.0e15], [50.0, 1.0e15], [50.0, 20.0]]
    h = Harness(parse_config(mconfig([memory_device("plc", rows, poll_interval_s=1.0)],
                                     [mloop("A", "plc", 0, 0, window_s=60.0)]), "<garbage>"))

    async def go() -> list[Any]:
        seen = []
        for _ in rows:
            await h.tick()
            seen.append(h.metric("stiction_loop_pv", loop="A"))
        return seen

    assert asyncio.run(go()) == [None, None, 1.0e15, 20.0]
    q = h.window("A")[3]
    assert q.tolist() == [Quality.BAD, Quality.BAD, Quality.GOOD, Quality.GOOD]


def test_a_reload_keeps_the_flag_of_a_device_behind_schedule() -> None:
    """The flag is the poller's state: a reload that keeps a device's connection keeps it
    (and its gauge); one that rebuilds the device starts it on schedule (gauge 0), never a
    gauge left at 1 that nothing clears."""
    raw = mconfig([memory_device("plc", wiggle(50, 2), poll_interval_s=1.0, repeat=True)],
                  [mloop("A", "plc", 0, 0, window_s=60.0)])
    first = Harness(parse_config(raw, "first"))
    lag = first.poller("plc").report.lag
    for t in range(3):
        first.poller("plc").report.schedule(1, 0.0, float(t), up=True)
    assert lag.behind and first.metric("stiction_device_behind_schedule", device="plc") == 1
    kept = build_runtime(parse_config(raw, "kept"), first.runtime, wall=first.time.wall,
                         metrics=first.metrics)
    assert kept.pollers[0].report.lag is lag
    assert first.metric("stiction_device_behind_schedule", device="plc") == 1
    raw["devices"][0]["poll_interval_s"] = 2.0
    raw["loops"][0]["window_s"] = 120.0
    rebuilt = build_runtime(parse_config(raw, "rebuilt"), kept, wall=first.time.wall,
                            metrics=first.metrics)
    assert not rebuilt.pollers[0].report.lag.behind
    assert first.metric("stiction_device_behind_schedule", device="plc") == 0
