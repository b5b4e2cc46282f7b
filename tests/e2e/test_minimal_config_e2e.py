"""Issue 16's first acceptance line: a config with only the required keys (2 devices, one
Modbus and one OPC UA, 3 loops) passes check-config and runs against the simulated PLC end
to end, its result blocks where the documented rule puts them (config order, 0, 20, 40 on
modbus_server.unit_id, which defaults to 1).

The file is used as written, with two exceptions made in code once it is loaded, because a
test cannot take fixed ports: the Modbus device keeps its default port 502 in the file (the
test checks it) and is pointed at the simulated PLC's free port, and the result server at
a free port instead of the default 5020."""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gateway_helpers import run, sim_config
from pymodbus.client import AsyncModbusTcpClient

from gateway.config import load_config
from gateway.runtime.gateway import Gateway
from gateway.wire.results import RESULT_BLOCK_SIZE, VERDICT_CODES, decode_block
from plcsim import PlcSim

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]
CLI = [sys.executable, "-m", "gateway.cli"]
FAKE = "gateway_fake_analyze:analyze"

MINIMAL = """\
devices:
  - {{name: plc1, protocol: modbus, host: 127.0.0.1}}
  - {{name: dcs1, protocol: opcua, endpoint: "opc.tcp://127.0.0.1:{opcua_port}"}}
loops:
  - name: FIC101
    device: plc1
    op: {{address: 0, type: float32}}
    pv: {{address: 2, type: float32}}
  - name: TIC201
    device: dcs1
    op: {{node: "ns=2;s=TIC201.OP"}}
    pv: {{node: "ns=2;s=TIC201.PV"}}
  - name: LIC102
    device: plc1
    op: {{address: 4, type: float32}}
    pv: {{address: 6, type: float32}}
"""


def test_only_the_required_keys_check_and_run_end_to_end(tmp_path: Path) -> None:
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    modbus_sim = sim_config([{"name": "FIC101", "scenario": "table4-case2"},
                             {"name": "LIC102", "scenario": "healthy"}])
    opcua_sim = sim_config([{"name": "TIC201", "scenario": "table4-case2"}], protocol="opcua")
    path = tmp_path / "gw.yaml"

    async def go() -> None:
        async with PlcSim(modbus_sim) as mb, PlcSim(opcua_sim) as ua:
            path.write_text(MINIMAL.format(opcua_port=ua.port))
            proc = await asyncio.to_thread(
                subprocess.run, [*CLI, "check-config", str(path)], capture_output=True,
                text=True, timeout=60, check=False)
            assert proc.returncode == 0, proc.stderr
            assert proc.stdout.splitlines() == [
                f"{path}: ok (2 device(s), 3 loop(s))",
                f"{path}: result_address assigned to 3 loop(s) without one (unit id, first "
                "of 20 registers):",
                "  FIC101: unit id 1, result_address 0",
                "  TIC201: unit id 1, result_address 20",
                "  LIC102: unit id 1, result_address 40"]

            config = load_config(path)
            plc = config.devices[0]
            assert (plc.options.port, plc.options.unit_id, plc.timeout_s,
                    plc.poll_interval_s) == (502, 1, 1.0, 1.0)
            devices = (dataclasses.replace(plc, options=dataclasses.replace(
                plc.options, port=mb.port)), config.devices[1])
            server = dataclasses.replace(config.modbus_server, listen=("127.0.0.1", 0))
            config = dataclasses.replace(config, devices=devices, modbus_server=server)

            async with Gateway(config, serve_http=False, analyze=FAKE) as gw:
                await asyncio.wait_for(gw.polling.wait(), 20)
                await asyncio.sleep(2.5)  # a few polls of each device
                assert all(p.polls >= 2 for p in gw.pollers)
                snap = gw.store.snapshot()
                for i, name in enumerate(gw.store.loops):
                    assert np.isfinite(snap.latest_op[i]) and np.isfinite(snap.latest_pv[i]), name
                assert await gw.scheduler.run_round() == 3
                blocks = await read_blocks(gw.result_port)
            expected = {"FIC101": 0, "TIC201": 20, "LIC102": 40}
            assert {lp.name: lp.result_address for lp in gw.config.loops} == expected
            for name, address in expected.items():
                fields = decode_block(blocks[address])
                assert fields["seq"] == 1, name
                assert fields["code"] != VERDICT_CODES["none"], name

    run(go(), 90)


async def read_blocks(port: int) -> dict[int, list[int]]:
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2)
    assert await client.connect()
    try:
        rsp = await client.read_input_registers(0, count=3 * RESULT_BLOCK_SIZE, device_id=1)
        assert not rsp.isError()
        regs = list(rsp.registers)
    finally:
        client.close()
    return {a: regs[a:a + RESULT_BLOCK_SIZE] for a in (0, 20, 40)}
