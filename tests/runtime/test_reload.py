"""Issue 6 item 3: bad config files are refused with every problem listed (check-config,
start-up, reload); a reload keeps unchanged loops' windows, starts added loops fresh and
drops removed loops from the registers and the metrics. (SIGHUP itself drives
:meth:`Gateway.reload` in the systemd subprocess test.)"""

from __future__ import annotations

import asyncio
import logging
import socket
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from prometheus_client import CollectorRegistry
from pymodbus.client import AsyncModbusTcpClient
from reliability_helpers import (
    FAKE,
    ScriptedPlc,
    device,
    feed,
    lateness,
    loop,
    raw_config,
    until,
)

from gateway.cli import main
from gateway.config import load_config
from gateway.inputs.base import Quality
from gateway.runtime.gateway import Gateway

BAD = """\
gateway: {analysis_intervall_s: 5}
metrics: {listen: "127.0.0.1:0"}
modbus_server: {listen: "127.0.0.1:0"}
devices:
  - {name: plc1, protocol: modbus, port: 502, unit_id: 1, poll_interval_s: 1,
     timeout_s: 1, max_registers_per_request: 200}
loops:
  - {name: A, device: plc9, op: {address: 0, type: float32},
     pv: {address: 2, type: float32, range: [5, 1]}, result_address: 0}
  - {name: B, device: plc1, op: {address: 0, type: float32},
     pv: {address: 2, type: float32}, result_address: 10}
"""

EXPECTED = [
    "gateway: unknown key 'analysis_intervall_s'",
    "device plc1: missing required key 'host'",
    "device plc1: key 'max_registers_per_request': must be in 1..125, was 200",
    "loop A: key 'device': unknown device 'plc9' (devices: plc1)",
    "loop A: key 'pv.range': must be finite with hi > lo, was [5, 1]",
    "loop B: key 'result_address': block 10..29 overlaps loop A (0..19)",
]


@pytest.mark.parametrize("command", ["check-config", "run"])
def test_bad_file_is_refused_listing_every_problem(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    argv = ["check-config", str(path)] if command == "check-config" else \
        ["run", "--config", str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert sorted(err) == sorted(f"{path}: {line}" for line in EXPECTED)


def _write(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _wiggle(k: int, plc: ScriptedPlc) -> None:
    for a in range(0, 40, 4):
        plc.set(a, 50.0 + 10.0 * np.sin((k + a) / 5.0))
        plc.set(a + 2, 20.0 + np.cos((k + a) / 7.0))


def _verdict(reg: CollectorRegistry, name: str) -> float | None:
    return reg.get_sample_value("stiction_loop_verdict",
                                {"loop": name, "verdict": "not_oscillating"})


@pytest.mark.timeout(60)
def test_reload_keeps_unchanged_windows_and_refuses_bad_files(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    out: dict[str, Any] = {}

    async def go() -> None:
        plc = await ScriptedPlc(64).start()
        feeder = asyncio.create_task(feed(plc, 0.02, _wiggle))
        dev = device("plc", plc.port, poll=0.05)
        dev2 = device("plc2", plc.port, poll=0.05)  # a second connection, left unchanged
        a, b, c = (loop("A", "plc", 0, 0), loop("B", "plc", 4, 20), loop("C", "plc", 8, 40))
        e = loop("E", "plc2", 16, 80)
        first = _write(tmp_path / "first.yaml",
                       raw_config([dev, dev2], [a, b, c, e], analysis_interval_s=0.5))
        c2 = {**c, "window_s": 20.0}
        d = loop("D", "plc", 12, 60)
        second = _write(tmp_path / "second.yaml",
                        raw_config([dev, dev2], [a, c2, d, e], analysis_interval_s=0.5))
        bad = tmp_path / "bad.yaml"
        bad.write_text(BAD)
        reg = CollectorRegistry()
        async with Gateway(load_config(first), registry=reg, analyze=FAKE,
                           serve_http=False) as gw:
            await until(lambda: gw.scheduler.rounds >= 2)
            bank = gw.pollers[0].groups[0].bank
            out["before"] = {n: bank.series([k]) for k, n in enumerate(bank.loops)}
            out["seq_before"] = {n: gw.store.results[i].seq for n, i in gw.store.index.items()}
            out["metrics_before"] = {n: _verdict(reg, n) for n in "ABCDE"}
            adapters = [p.source for p in gw.pollers]
            poller0 = gw.pollers[0]
            assert await gw.reload(second)
            out["same_adapter"] = [p.source is x for p, x in zip(gw.pollers, adapters,
                                                                  strict=True)]
            banks = {n: s.bank for s in gw.pollers[0].groups for n in s.bank.loops}
            out["after"] = {n: banks[n].series([list(banks[n].loops).index(n)])
                            for n in ("A", "C", "D")}
            out["seq_after"] = {n: (r.seq if r else None) for n, r in
                                zip(gw.store.loops, gw.store.results, strict=True)}
            out["metrics_after"] = {n: _verdict(reg, n) for n in "ABCDE"}
            client = AsyncModbusTcpClient("127.0.0.1", port=gw.result_port, timeout=2)
            await client.connect()
            rsp = await client.read_holding_registers(0, count=80, device_id=1)
            out["registers"] = list(rsp.registers)
            client.close()
            # a bad file on reload: refused, the running config stays, polling goes on
            polls = gw.pollers[0].polls
            out["bad_reload"] = await gw.reload(bad)
            out["config_after_bad"] = gw.config.source
            await asyncio.sleep(0.5)
            out["polls_after_bad"] = gw.pollers[0].polls - polls
            out["starts"] = poller0.tick_starts + gw.pollers[0].tick_starts
            out["missed"] = poller0.missed_ticks + gw.pollers[0].missed_ticks
            out["reconnects"] = gw.pollers[1].reconnects
        feeder.cancel()
        await plc.stop()

    asyncio.run(asyncio.wait_for(go(), 50))
    before, after = out["before"], out["after"]
    # A unchanged: its window carried over sample for sample
    n_a = len(before["A"][0])
    assert n_a >= 20
    np.testing.assert_array_equal(after["A"][1][0][:n_a], before["A"][1][0])
    np.testing.assert_array_equal(after["A"][0][:n_a], before["A"][0])
    assert out["seq_after"]["A"] == out["seq_before"]["A"]  # its result too
    # C changed its window, D is new: both start fresh, with no result
    # (D shares A's bank, so it has A's rows, all MISSING: nothing from before the reload)
    assert len(after["C"][0]) <= 2
    assert (after["D"][3][0][:-2] == Quality.MISSING).all()
    assert out["seq_after"]["C"] is None and out["seq_after"]["D"] is None
    # B vanished from the metrics and the registers
    assert out["metrics_before"] == {"A": 1.0, "B": 1.0, "C": 1.0, "D": None, "E": 1.0}
    assert out["metrics_after"]["B"] is None and out["metrics_after"]["A"] == 1.0
    assert "B" not in out["seq_after"]
    regs = out["registers"]
    assert regs[0] == 1 and regs[1] == out["seq_before"]["A"]  # A: not_oscillating, seq
    assert regs[20:40] == [0] * 20  # B's block is empty
    assert regs[40] == 0 and regs[60] == 0  # C and D: no result yet
    # the device kept its connection and its schedule
    # plc's points changed: a new adapter (connection); plc2 kept its connection
    assert out["same_adapter"] == [False, True]
    assert out["reconnects"] == 0 and out["missed"] == 0
    assert float(lateness(out["starts"], 0.05).max()) < 0.05
    # the bad file
    assert out["bad_reload"] is False
    assert out["config_after_bad"].endswith("second.yaml")
    assert out["polls_after_bad"] >= 5
    refused = [r.getMessage() for r in caplog.records if "reload refused" in r.getMessage()]
    assert len(refused) == 1
    for line in EXPECTED:
        assert line in refused[0]
    assert any("reloaded" in r.getMessage() and "1 added, 1 removed" in r.getMessage()
               for r in caplog.records)


def test_no_port_is_bound_by_a_refused_start(tmp_path: Path) -> None:
    """Start-up with a bad file stops before opening anything: the ports stay free."""
    path = tmp_path / "bad.yaml"
    port = _free()
    path.write_text(BAD.replace("127.0.0.1:0\"}\nmodbus", f"127.0.0.1:{port}\"}}\nmodbus"))
    assert main(["run", "--config", str(path)]) == 2
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))  # would fail if the gateway had bound it


def _free() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.timeout(60)
def test_reload_that_fails_while_building_keeps_polling(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A config that validates but cannot be applied (here: the adapter of a new device
    cannot be built) leaves the running config and its pollers in place."""
    import gateway.inputs.modbus as modbus_plugin  # noqa: PLC0415

    out: dict[str, Any] = {}

    async def go() -> None:
        plc = await ScriptedPlc(16).start()
        feeder = asyncio.create_task(feed(plc, 0.02, _wiggle))
        first = raw_config([device("plc", plc.port, poll=0.05)], [loop("A", "plc", 0, 0)])
        second = raw_config([device("plc", plc.port, poll=0.05),
                             device("new", plc.port, poll=0.05)],
                            [loop("A", "plc", 0, 0), loop("N", "new", 4, 20)])
        async with Gateway(load_config(_write(tmp_path / "a.yaml", first)),
                           registry=CollectorRegistry(), analyze=FAKE,
                           serve_http=False) as gw:
            await until(lambda: gw.pollers[0].good_polls >= 3)

            def broken(*_: Any, **__: Any) -> Any:
                raise RuntimeError("adapter cannot be built")

            monkeypatch.setattr(modbus_plugin, "create_input", broken)
            out["ok"] = await gw.reload(_write(tmp_path / "b.yaml", second))
            polls = gw.pollers[0].good_polls
            await asyncio.sleep(0.5)
            out["polls"] = gw.pollers[0].good_polls - polls
            out["loops"] = list(gw.store.loops)
        feeder.cancel()
        await plc.stop()

    asyncio.run(asyncio.wait_for(go(), 50))
    assert out["ok"] is False
    assert out["loops"] == ["A"]
    assert out["polls"] >= 5
    assert any("reload failed, keeping the running config" in r.getMessage()
               for r in caplog.records)


@pytest.mark.timeout(60)
def test_reload_moves_loops_between_result_unit_ids(tmp_path: Path) -> None:
    out: dict[str, Any] = {}

    async def read(port: int, unit: int, address: int) -> list[int] | int:
        """The 20 registers of a block, or the exception code."""
        client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
        await client.connect()
        try:
            rsp = await client.read_holding_registers(address, count=20, device_id=unit)
            return int(rsp.exception_code) if rsp.isError() else list(rsp.registers)
        finally:
            client.close()

    async def go() -> None:
        plc = await ScriptedPlc(64).start()
        feeder = asyncio.create_task(feed(plc, 0.02, _wiggle))
        dev = device("plc", plc.port, poll=0.05)
        a, b = loop("A", "plc", 0, 0), loop("B", "plc", 4, 20)
        one = _write(tmp_path / "one.yaml", raw_config([dev], [a, b], analysis_interval_s=0.5))
        # B moves to unit id 2 (same address as A), C is new there: a unit id the running
        # server has no device for
        b2, c2 = {**b, "result_address": 0, "result_unit_id": 2}, \
            {**loop("C", "plc", 8, 20), "result_unit_id": 2}
        two = _write(tmp_path / "two.yaml",
                     raw_config([dev], [a, b2, c2], analysis_interval_s=0.5))
        async with Gateway(load_config(one), registry=CollectorRegistry(), analyze=FAKE,
                           serve_http=False) as gw:
            await until(lambda: gw.scheduler.rounds >= 2)
            out["seq_b"] = gw.store.results[gw.store.index["B"]].seq
            out["unit2_before"] = await read(gw.result_port, 2, 0)
            first = gw.result_server.server
            assert await gw.reload(two)
            out["restarted"] = gw.result_server.server is not first
            out["b_on_2"] = await read(gw.result_port, 2, 0)
            out["c_on_2"] = await read(gw.result_port, 2, 20)
            out["a_on_1"] = await read(gw.result_port, 1, 0)
            out["old_b_on_1"] = await read(gw.result_port, 1, 20)
            second = gw.result_server.server
            assert await gw.reload(one)  # back: unit id 2 no longer used
            out["rebound"] = gw.result_server.server is second
            out["unit2_after"] = await read(gw.result_port, 2, 0)
            out["b_back_on_1"] = await read(gw.result_port, 1, 20)
        feeder.cancel()
        await plc.stop()

    asyncio.run(asyncio.wait_for(go(), 50))
    assert out["unit2_before"] == 0x0A
    assert out["restarted"]
    b_on_2 = out["b_on_2"]
    assert isinstance(b_on_2, list)
    assert b_on_2[0] == 1  # B's result carried over (not_oscillating) ...
    assert b_on_2[1] == out["seq_b"] % 65536  # ... with its sequence number
    assert isinstance(out["c_on_2"], list)
    assert out["c_on_2"][0] == 0  # C: new, no result yet
    assert isinstance(out["a_on_1"], list)
    assert out["a_on_1"][0] == 1
    assert out["old_b_on_1"] == 2  # B's old block on unit id 1 is gone (illegal address)
    assert out["rebound"]  # no new unit id: the running server was rebound
    assert out["unit2_after"] == 0x0A
    assert isinstance(out["b_back_on_1"], list)
    assert out["b_back_on_1"][0] == 1
