"""Modbus input: decoding, request planning, coalescing counted at the server, errors."""

from __future__ import annotations

import asyncio
import math
import struct

import numpy as np
import pytest
from gateway_helpers import gateway_for, run, sim_config
from hypothesis import given, settings
from hypothesis import strategies as st

from bench._net import free_port
from gateway.core.points import PointSpec, PointTable, Quality
from gateway.errors import DeviceError
from gateway.inputs.modbus import ModbusDeviceOptions, ModbusInput, ModbusPoint, plan_requests
from gateway.runtime.gateway import Gateway
from gateway.wire.codec import TYPES, decode_registers, encode_values
from gateway.wire.registers import RegisterServer
from plcsim import PlcSim

ORDERS = ["big", "little"]
FAKE = "gateway_fake_analyze:analyze"  # no analysis runs here; keeps stiction.analyze out


def test_decode_known_layouts() -> None:
    # 123.456 as float32 is 0x42F6E979: ABCD big/big, CDAB little words, BADC swapped bytes
    assert decode_registers(np.array([0x42F6, 0xE979]), "float32")[0] == pytest.approx(123.456)
    assert decode_registers(np.array([0xE979, 0x42F6]), "float32", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0xF642, 0x79E9]), "float32", "big", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0x79E9, 0xF642]), "float32", "little", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0xFFFF]), "int16")[0] == -1
    assert decode_registers(np.array([0xFFFF]), "uint16")[0] == 65535
    assert decode_registers(np.array([0xFFFF, 0xFFFE]), "int32")[0] == -2
    assert decode_registers(np.array([0x0001, 0x0000]), "uint32")[0] == 65536
    regs = np.frombuffer(struct.pack(">d", -2.5), dtype=">u2").astype(np.uint16)
    assert decode_registers(regs, "float64")[0] == -2.5


@settings(max_examples=200, deadline=None, derandomize=True)
@given(typ=st.sampled_from(sorted(TYPES)), word=st.sampled_from(ORDERS),
       byte=st.sampled_from(ORDERS), seed=st.integers(0, 2**32 - 1))
def test_encode_decode_round_trip(typ: str, word: str, byte: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    width, dtype = TYPES[typ]
    if dtype[1] == "f":
        values = rng.normal(0, 1e3, 8).astype(dtype).astype(np.float64)
    else:
        info = np.iinfo(np.dtype(dtype))
        values = rng.integers(info.min, info.max, 8, endpoint=True).astype(np.float64)
    regs = encode_values(values, typ, word, byte)
    assert regs.shape == (8, width)
    np.testing.assert_array_equal(decode_registers(regs, typ, word, byte), values)


def test_plan_merges_tables_gaps_and_splits_at_the_limit() -> None:
    pts = [ModbusPoint(a, "float32") for a in range(0, 400, 2)]
    reqs, first = plan_requests(pts, 125)
    assert [(r.address, r.count) for r in reqs] == [(0, 125), (125, 125), (250, 125), (375, 25)]
    assert first.tolist() == list(range(0, 400, 2))
    pts = [ModbusPoint(0, "float32"), ModbusPoint(10, "int16"), ModbusPoint(3, "uint16"),
           ModbusPoint(20, "int16", table="input"), ModbusPoint(6, "float64")]
    reqs, first = plan_requests(pts, 125, merge_gap=4)
    assert [(r.table, r.address, r.count) for r in reqs] == [("holding", 0, 11),
                                                              ("input", 20, 1)]
    assert first.tolist() == [0, 10, 3, 11, 6]
    reqs, _ = plan_requests(pts, 125, merge_gap=0)
    assert [(r.address, r.count) for r in reqs] == [(0, 2), (3, 1), (6, 5), (20, 1)]


@pytest.mark.parametrize(("loops", "max_regs"), [(60, 125), (60, 50), (7, 125), (100, 7)])
def test_coalescing_counted_at_the_server(loops: int, max_regs: int) -> None:
    """N loops in one contiguous block (4 registers each): the gateway sends
    ceil(registers / max_registers_per_request) requests per poll, counted by the server."""
    expected = math.ceil(4 * loops / max_regs)
    sim = sim_config([{"name": f"L{i:03d}", "scenario": "healthy"} for i in range(loops)],
                     time_scale=20.0)

    async def go() -> tuple[int, int, int, float | None]:
        async with PlcSim(sim) as plc:
            cfg = gateway_for(sim, plc.port, device={"max_registers_per_request": max_regs},
                              analysis_interval_s=1e6)
            async with Gateway(cfg, analyze=FAKE) as gw:
                await asyncio.sleep(1.0)
                poller = gw.pollers[0]
                before, polls_before = plc.server.requests, poller.good_polls
                await asyncio.sleep(1.0)
                served = plc.server.requests - before
                polls = poller.good_polls - polls_before
                sent = gw.registry.get_sample_value("stiction_poll_requests_total",
                                                    {"device": "plc-sim"})
                return served, polls, poller.good_polls, sent

    served, polls, total_polls, sent = run(go())
    assert polls >= 10  # 20 polls/s for 1 s
    # a poll may straddle the two counter reads: allow one partial poll either side
    assert abs(served - polls * expected) <= expected
    assert sent is not None
    assert sent == total_polls * expected


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
