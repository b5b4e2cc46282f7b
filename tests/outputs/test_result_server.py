"""The Modbus result server output: blocks per unit id, read-only, a view of the store."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator

import numpy as np
import pytest
from gateway_helpers import run
from pymodbus.client import AsyncModbusTcpClient
from result_fixtures import STICKY, sample_store

from gateway.config import LoopConfig, PointConfig, ResultServerSettings
from gateway.inputs.modbus import ModbusPoint
from gateway.outputs.modbus_server import ResultServer
from gateway.wire.codec import decode_registers
from gateway.wire.results import result_block

NONE = result_block(None, code=0).tolist()  # a block without assessment (floats NaN)


def _loop(name: str, address: int, unit: int | None = None) -> LoopConfig:
    point = PointConfig(ModbusPoint(0, "float32"))
    return LoopConfig(name, "plc", point, point, result_address=address, result_unit_id=unit)


def _decode_block(regs: list[int] | np.ndarray, word_order: str = "big") -> dict[str, float]:
    r = np.asarray(regs, dtype=np.uint16)
    f = decode_registers(r[2:12], "float32", word_order)
    return {"code": int(r[0]), "seq": int(r[1]), "si": f[0], "fd": f[1], "fs": f[2],
            "period": f[3], "jump": f[4],
            "t": decode_registers(r[12:14], "uint32", word_order)[0],
            "fill": decode_registers(r[14:16], "float32", word_order)[0],
            "confidence": decode_registers(r[16:18], "float32", word_order)[0],
            "reserved": int(np.abs(r[18:20]).sum())}


@contextlib.asynccontextmanager
async def _client_of(server: ResultServer) -> AsyncIterator[AsyncModbusTcpClient]:
    """Start ``server`` and yield a Modbus client connected to it; close both after."""
    await server.start()
    client = AsyncModbusTcpClient("127.0.0.1", port=server.port, timeout=2, retries=0)
    try:
        assert await client.connect()
        yield client
    finally:
        client.close()
        await server.stop()


def test_result_server_serves_blocks_and_refuses_writes() -> None:
    st = sample_store()
    loops = [_loop("FIC101", 0), _loop("FIC401", 20), _loop("TIC301", 100)]
    settings = ResultServerSettings(listen=("127.0.0.1", 0), unit_id=1)

    async def go() -> None:
        server = ResultServer(settings, loops, st)
        async with _client_of(server) as client:
            holding = await client.read_holding_registers(0, count=40, device_id=1)
            inputs = await client.read_input_registers(0, count=40, device_id=1)
            assert not holding.isError()
            assert holding.registers == inputs.registers
            assert _decode_block(holding.registers[:20])["fd"] == pytest.approx(27.0)
            assert _decode_block(holding.registers[20:40])["code"] == 2
            tic = await client.read_input_registers(100, count=20, device_id=1)
            assert tic.registers == NONE  # no result yet: code 0, floats NaN
            # every kind of write is answered with exception 1 (illegal function)
            before = list(holding.registers)
            for rsp in [await client.write_register(0, 9, device_id=1),
                        await client.write_registers(2, [1, 2, 3], device_id=1),
                        await client.write_coil(0, True, device_id=1),
                        await client.write_coils(0, [True, False], device_id=1),
                        await client.readwrite_registers(read_address=0, read_count=2,
                                                         write_address=0, values=[7, 7],
                                                         device_id=1)]:
                assert rsp.isError()
                assert rsp.exception_code == 1
            after = await client.read_holding_registers(0, count=40, device_id=1)
            assert after.registers == before
            assert server.server.refused_writes == 5
            # a new assessment shows up at once; a wrong unit id gets exception 0x0A
            st.set_result(1, STICKY, t=1_700_000_600.0, window_fill=1.0, samples=1)
            again = await client.read_input_registers(20, count=20, device_id=1)
            assert _decode_block(again.registers)["code"] == 4
            assert _decode_block(again.registers)["seq"] == 2
            wrong = await client.read_input_registers(0, count=2, device_id=9)
            assert wrong.isError()
            assert wrong.exception_code == 0x0A
            past = await client.read_input_registers(110, count=20, device_id=1)
            assert past.isError()

    run(go(), 30)


def test_result_server_serves_each_unit_id_its_own_blocks() -> None:
    st = sample_store()
    # FIC101 on the default unit id 1, FIC401 at the same address on unit id 2,
    # TIC301 on unit id 3 further up
    loops = [_loop("FIC101", 0), _loop("FIC401", 0, unit=2), _loop("TIC301", 40, unit=3)]
    settings = ResultServerSettings(listen=("127.0.0.1", 0), unit_id=1)

    async def go() -> None:
        server = ResultServer(settings, loops, st)
        assert sorted(server.images) == [1, 2, 3]
        async with _client_of(server) as client:
            one = await client.read_input_registers(0, count=20, device_id=1)
            two = await client.read_input_registers(0, count=20, device_id=2)
            two_h = await client.read_holding_registers(0, count=20, device_id=2)
            assert _decode_block(one.registers)["code"] == 4  # FIC101
            assert _decode_block(two.registers)["code"] == 2  # FIC401
            assert _decode_block(two.registers)["fill"] == pytest.approx(0.25)
            assert two_h.registers == two.registers
            three = await client.read_holding_registers(40, count=20, device_id=3)
            assert three.registers == NONE  # TIC301: no result yet
            assert (await client.read_holding_registers(60, count=1, device_id=2)).isError()
            # a write to the second unit id is refused, nothing changes
            for rsp in [await client.write_register(0, 9, device_id=2),
                        await client.write_registers(0, [1, 2], device_id=2)]:
                assert rsp.isError()
                assert rsp.exception_code == 1
            assert server.server.refused_writes == 2
            assert (await client.read_input_registers(0, count=20, device_id=2)
                    ).registers == two.registers
            # a new result reaches its own unit id only
            st.set_result(2, STICKY, t=1_700_000_900.0, window_fill=1.0, samples=1)
            three = await client.read_input_registers(40, count=20, device_id=3)
            assert _decode_block(three.registers)["code"] == 4
            assert (await client.read_input_registers(40, count=1, device_id=1)).isError()
            # unit ids no loop uses: exception 0x0A, reads and writes alike
            for unit in (4, 9, 247):
                rsp = await client.read_input_registers(0, count=2, device_id=unit)
                assert rsp.isError()
                assert rsp.exception_code == 0x0A
            rsp = await client.write_register(0, 9, device_id=9)
            assert rsp.isError()
            assert rsp.exception_code == 0x0A
            # rebound without unit id 3 (e.g. a reload removed TIC301's unit id): gone
            running = server.server
            server.rebind([*loops[:2], _loop("TIC301", 40, unit=2)], st)
            rsp = await client.read_input_registers(40, count=20, device_id=3)
            assert rsp.isError()
            assert rsp.exception_code == 0x0A
            moved = await client.read_input_registers(40, count=20, device_id=2)
            assert _decode_block(moved.registers)["code"] == 4
            # a unit id new to the server is served by the running one, on the same connection
            server.rebind([*loops[:2], _loop("TIC301", 40, unit=5)], st)
            new = await client.read_input_registers(40, count=20, device_id=5)
            assert _decode_block(new.registers)["code"] == 4
            assert server.server is running

    run(go(), 30)


def test_result_server_with_unit_id_0_answers_every_unserved_id() -> None:
    st = sample_store()
    loops = [_loop("FIC101", 0), _loop("FIC401", 0, unit=2)]
    settings = ResultServerSettings(listen=("127.0.0.1", 0), unit_id=0)

    async def go() -> None:
        server = ResultServer(settings, loops, st)
        async with _client_of(server) as client:
            for unit in (0, 1, 9):  # the catch-all: FIC101
                rsp = await client.read_input_registers(0, count=20, device_id=unit)
                assert _decode_block(rsp.registers)["code"] == 4
            rsp = await client.read_input_registers(0, count=20, device_id=2)
            assert _decode_block(rsp.registers)["code"] == 2

    run(go(), 30)
