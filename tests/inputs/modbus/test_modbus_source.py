"""Modbus source against real servers on 127.0.0.1: coalescing counted at the server, raw
values, and each kind of failure mapped to a DeviceError (what the poller then does with
it is tested in memory, tests/runtime/test_poller.py)."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest
from gateway_helpers import run
from reliability_helpers import SilentServer

from bench._net import free_port
from gateway.core.points import PointSpec, PointTable, Quality
from gateway.errors import DeviceError
from gateway.inputs.modbus import ModbusDeviceOptions, ModbusInput, ModbusPoint
from gateway.wire.codec import encode_values
from gateway.wire.registers import RegisterServer


def _float_points(loops: int) -> list[PointSpec]:
    """OP float32 at 4k, PV at 4k + 2, for loops 0..loops-1."""
    return [PointSpec(f"L{k:03d}", role, ModbusPoint(4 * k + 2 * j, "float32"))
            for k in range(loops) for j, role in enumerate(("op", "pv"))]


@pytest.mark.parametrize(("loops", "max_regs"), [(60, 125), (60, 50), (7, 125), (100, 7)])
def test_coalescing_counted_at_the_server(loops: int, max_regs: int) -> None:
    """N loops in one contiguous block (4 registers each): the source sends
    ceil(registers / max_registers_per_request) requests per read, counted by the server,
    and says so in ``ReadResult.requests`` (which the poller adds to
    stiction_poll_requests_total)."""
    expected = math.ceil(4 * loops / max_regs)
    values = np.arange(2 * loops, dtype=np.float64) + 0.5
    image = encode_values(values, "float32").reshape(-1)

    async def go() -> tuple[int, list[int]]:
        server = RegisterServer({"holding": image, "input": image}, host="127.0.0.1", port=0)
        await server.start()
        opts = ModbusDeviceOptions("127.0.0.1", server.port, 1, max_regs)
        source = ModbusInput("plc", opts, _float_points(loops), timeout_s=1.0)
        try:
            await source.connect()
            before = server.requests
            results = [await source.read() for _ in range(10)]
            served = server.requests - before
        finally:
            await source.close()
            await server.stop()
        for res in results:
            np.testing.assert_array_equal(res.values, values)
        return served, [r.requests for r in results]

    served, sent = run(go(), 30)
    assert sent == [expected] * 10
    assert served == 10 * expected


def test_exception_for_one_block_is_a_gap_and_dead_device_raises() -> None:
    image = encode_values([12.5, 50.0], "float32").reshape(-1)  # registers 0..3
    points = [PointSpec("A", "op", ModbusPoint(0, "float32"), 2.0, 1.0),
              PointSpec("A", "pv", ModbusPoint(2, "float32")),
              PointSpec("B", "op", ModbusPoint(200, "int16"))]  # beyond the image

    async def go() -> None:
        server = RegisterServer({"holding": image, "input": image}, host="127.0.0.1", port=0)
        await server.start()
        dev = ModbusInput("plc", ModbusDeviceOptions("127.0.0.1", server.port, 1), points,
                          timeout_s=1.0)
        try:
            await dev.connect()
            res = await dev.read()
            assert res.requests == 2
            np.testing.assert_array_equal(res.values[:2], [12.5, 50.0])  # raw: unscaled
            assert np.isnan(res.values[2])
            assert res.quality.tolist() == [Quality.GOOD, Quality.GOOD, Quality.NO_COMM]
            assert [e.kind for e in res.errors] == ["exception"]
        finally:
            await dev.close()
            await server.stop()
        dead = ModbusInput("gone", ModbusDeviceOptions("127.0.0.1", free_port(), 1), points,
                           timeout_s=0.5)
        with pytest.raises(DeviceError) as info:
            await dead.connect()
        assert info.value.kind == "connect"
        assert info.value.device == "gone"
        with pytest.raises(DeviceError) as info:
            await dead.read()
        assert info.value.kind == "connect"
        await dead.close()

    run(go(), 30)


def test_nan_and_inf_values_are_bad_quality_not_numbers() -> None:
    image = encode_values([math.nan, math.inf, 3.0], "float32").reshape(-1)
    points = [PointSpec("A", "op", ModbusPoint(0, "float32")),
              PointSpec("A", "pv", ModbusPoint(2, "float32")),
              PointSpec("B", "op", ModbusPoint(4, "float32"))]

    async def go() -> None:
        server = RegisterServer({"holding": image, "input": image}, host="127.0.0.1", port=0)
        await server.start()
        dev = ModbusInput("plc", ModbusDeviceOptions("127.0.0.1", server.port, 1), points)
        try:
            await dev.connect()
            res = await dev.read()
        finally:
            await dev.close()
            await server.stop()
        # the source only decodes; core.points flags NaN and inf BAD, for every protocol
        assert res.quality.tolist() == [Quality.GOOD] * 3
        assert np.isnan(res.values[0]) and np.isinf(res.values[1])
        values, quality = PointTable(points).engineering(res.values, res.quality)
        assert quality.tolist() == [Quality.BAD, Quality.BAD, Quality.GOOD]
        assert np.isnan(values[:2]).all()
        assert values[2] == 3.0

    run(go(), 30)


def test_silent_server_times_out_and_a_server_back_on_its_port_is_read_again() -> None:
    """A PLC that accepts TCP but never answers: DeviceError(timeout) within the timeout.
    A PLC that goes away: DeviceError(connect or timeout); once it is back on its port,
    closing and connecting again (as the poller does) reads it."""
    image = encode_values([1.0, 2.0], "float32").reshape(-1)
    points = [PointSpec("A", "op", ModbusPoint(0, "float32")),
              PointSpec("A", "pv", ModbusPoint(2, "float32"))]

    async def go() -> tuple[str, float, list[str], list[float]]:
        async with SilentServer() as silent:
            mute = ModbusInput("mute", ModbusDeviceOptions("127.0.0.1", silent.port, 1),
                               points, timeout_s=0.3)
            await mute.connect()
            t0 = asyncio.get_running_loop().time()
            with pytest.raises(DeviceError) as info:
                await mute.read()
            waited = asyncio.get_running_loop().time() - t0
            await mute.close()
        server = RegisterServer({"holding": image, "input": image}, host="127.0.0.1", port=0)
        await server.start()
        port = server.port
        flaky = ModbusInput("flaky", ModbusDeviceOptions("127.0.0.1", port, 1), points,
                            timeout_s=0.3)
        await flaky.connect()
        assert (await flaky.read()).values.tolist() == [1.0, 2.0]
        await server.stop()
        kinds = []
        for _ in range(2):
            with pytest.raises(DeviceError) as gone:
                await flaky.read()
            kinds.append(gone.value.kind)
        await flaky.close()
        back = RegisterServer({"holding": image, "input": image}, host="127.0.0.1",
                              port=port)
        await back.start()
        try:
            await flaky.connect()
            again = (await flaky.read()).values.tolist()
        finally:
            await flaky.close()
            await back.stop()
        return info.value.kind, waited, kinds, again

    kind, waited, kinds, again = run(go(), 30)
    assert kind == "timeout" and waited < 1.5
    assert set(kinds) <= {"connect", "timeout"}
    assert again == [1.0, 2.0]
