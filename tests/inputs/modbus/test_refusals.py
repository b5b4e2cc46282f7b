"""Issue 23 against an in-process Modbus server (gateway.wire.registers, loopback): a wrong
unit id is the device down with the reason in words; a register outside the PLC's map is
named in words with the fix and the tag-list line; ``probe`` calls an off-by-one float32
IMPLAUSIBLE with its likely cause instead of GOOD."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from gateway.config import load_config
from gateway.inputs.base import ReadResult
from gateway.inputs.modbus.exceptions import exception_name, refusal
from gateway.runtime.poller import all_refused
from gateway.runtime.probe import DeviceProbe, format_probe, probe
from gateway.runtime.reload import device_points, plugin_source
from gateway.wire.codec import encode_values
from gateway.wire.registers import RegisterServer

T = TypeVar("T")


def image() -> np.ndarray:
    """100 holding registers: loop k's OP (50 + k) at 4k, its PV (20 + k) at 4k + 2."""
    values = [v for k in range(25) for v in (50.0 + k, 20.0 + k)]
    return encode_values(values, "float32", "big").reshape(-1)


def serve(fn: Callable[[int], Awaitable[T]]) -> T:
    async def go() -> T:
        img = image()
        server = RegisterServer({"holding": img, "input": img}, host="127.0.0.1", port=0)
        await server.start()
        try:
            return await fn(server.port)
        finally:
            await server.stop()
    return asyncio.run(go())


def config(tmp: Path, port: int, rows: str, unit_id: int = 1) -> Any:
    (tmp / "loops.csv").write_text("name,device,op,pv,type\n" + rows)
    (tmp / "gw.yaml").write_text(
        f"devices: [{{name: plc1, protocol: modbus, host: 127.0.0.1, port: {port}, "
        f"unit_id: {unit_id}}}]\nloops_csv: loops.csv\n")
    return load_config(tmp / "gw.yaml")


async def read_once(cfg: Any) -> ReadResult:
    device = cfg.devices[0]
    source = plugin_source(device, device_points(cfg.loops), 1.0)
    try:
        await source.connect()
        return await source.read()
    finally:
        await source.close()


def test_a_wrong_unit_id_is_every_request_refused_in_words(tmp_path: Path) -> None:
    """Item 1 and 5: unit_id 5 on a PLC that serves 1 answers exception 10 to each
    request; the read is all refused (the poller calls the device down with this
    reason), and the words say what to do."""
    async def go(port: int) -> ReadResult:
        rows = "FIC101,plc1,0,2,float32\nLIC201,plc1,300,302,float32\n"
        return await read_once(config(tmp_path, port, rows, unit_id=5))

    result = serve(go)
    assert len(result.errors) == 2  # two requests (registers 0-3 and 300-303), both refused
    first = result.errors[0]
    assert first.reason == "unit id 5 not served"
    assert str(first).startswith("device plc1: holding 0+4: gateway path unavailable "
                                 "(exception 10): unit id 5 is not served by the PLC")
    assert "set the device's unit_id to the one it serves" in str(first)
    down = all_refused(result)
    assert down is not None and down.reason == "unit id 5 not served"
    assert str(down).startswith("device plc1: all 2 requests refused, the first: holding "
                                "0+4: gateway path unavailable")


def test_a_register_outside_the_map_is_named_with_the_fix_and_the_tag_list_line(
        tmp_path: Path) -> None:
    """Item 5: ``holding 40001+4: exception code 2`` became the exception in words, the
    loop and its tag-list line, and the hint that addresses are 0-based; the other loop is
    read, so the device stays up (not all refused)."""
    async def go(port: int) -> ReadResult:
        rows = "FIC101,plc1,0,2,float32\nTIC301,plc1,40001,40003,float32\n"
        return await read_once(config(tmp_path, port, rows))

    result = serve(go)
    (err,) = result.errors
    assert err.reason == "illegal data address"
    text = str(err)
    assert text.startswith("device plc1: holding 40001+4: illegal data address (exception "
                           "2): registers 40001..40004 are outside the PLC's map")
    assert "check the address of TIC301 op and pv (loops.csv: line 3)" in text
    assert "addresses are 0-based: 40001 is 0" in text
    assert "TIC301 op at 40001 looks like a 1-based 4xxxx reference: register 0?" in text
    assert all_refused(result) is None
    assert result.quality.tolist()[:2] == [0, 0]


def test_every_exception_code_has_words_and_a_fix() -> None:
    assert exception_name(10) == "gateway path unavailable"
    assert exception_name(11) == "gateway target device failed to respond"
    assert exception_name(99) == "exception code 99"
    reason, text = refusal(11, "input", 0, 10, unit=7, points=[])
    assert reason == "unit id 7 not answering"
    assert "usually" not in text and "check the device's unit_id" in text
    for code in (1, 3, 4, 6):
        reason, text = refusal(code, "holding", 10, 2, unit=1, points=[])
        assert reason == exception_name(code) and f"(exception {code})" in text


def test_probe_calls_an_off_by_one_float_implausible_with_its_likely_cause(
        tmp_path: Path) -> None:
    """Item 2: an OP read one register late is a float made of two halves; probe printed
    it GOOD. Now it is IMPLAUSIBLE, saying why and what is likely wrong; the right
    address is GOOD."""
    async def go(port: int) -> list[DeviceProbe]:
        rows = "FIC101,plc1,1,6,float32\nLIC201,plc1,4,10,float32\n"
        return await probe(config(tmp_path, port, rows))

    (dev,) = serve(go)
    table = format_probe([dev])
    lines = table.splitlines()
    assert lines[0].split()[-2:] == ["quality", "status"]
    off = next(line for line in lines if line.startswith("FIC101  op"))
    assert "IMPLAUSIBLE" in off and "subnormal" in off and "address off by one" in off
    assert [r.shown_quality for r in dev.rows] == ["IMPLAUSIBLE", "GOOD", "GOOD", "GOOD"]
    assert not dev.ok
