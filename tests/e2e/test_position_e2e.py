"""End to end, the valve's position (issue 30): plc-sim serves a sticky valve's position
(the simulated valve's own) beside OP and PV, its ``--write-gateway-config`` reads it as
the loop's ``position:``, and the gateway (stiction.analyze in worker processes) decides the
loop from the valve's travel; a Modbus client reads the slip from the jump register and the
metrics give the band: both within 10 % of the simulated valve (He's model, fs 0.08,
fd 0.27, K 1.99: band 2 fs - J = 0.540, slip J = K (fs - fd) = 0.0597)."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest
from gateway_helpers import run, scrape
from prometheus_client.parser import text_string_to_metric_families
from pymodbus.client import AsyncModbusTcpClient

from gateway.config import parse_config
from gateway.runtime.gateway import Gateway
from gateway.wire.codec import decode_registers
from gateway.wire.results import VERDICT_CODES
from plcsim import PlcSim, parse_sim_config
from plcsim.gateway_yaml import gateway_config
from stiction.diagnosis.travel import MEASURED

pytestmark = [pytest.mark.e2e, pytest.mark.slow]

SLIP = 1.99 * (0.30 - 0.27)
BAND = 2 * 0.30 - SLIP


def test_a_loop_decided_from_its_valve_travel_over_modbus(tmp_path: Path) -> None:
    sim_cfg = parse_sim_config({
        "listen": "127.0.0.1:0", "time_scale": 10.0,
        "loops": [{"name": "FIC101", "scenario": "table4-case2", "noise": 0.02,
                   "window_s": 500}]})
    gw_raw = gateway_config(sim_cfg, analysis_interval_s=30.0,
                            metrics_listen="127.0.0.1:0", result_listen="127.0.0.1:0")
    assert gw_raw["loops"][0]["position"] == {"address": sim_cfg.position_address(0),
                                              "type": "float32"}
    gw_raw["gateway"]["state_file"] = str(tmp_path / "gw.state")
    gw_raw["verdict_hysteresis"] = {"rounds": 1}  # publish each round's verdict

    async def go() -> tuple[list[int], str, str]:
        async with PlcSim(sim_cfg) as sim:
            gw_raw["devices"][0]["port"] = sim.port
            gateway = Gateway(parse_config(gw_raw, "<e2e>"))
            gateway.align_polls(sim.mid_step())
            async with gateway as gw:
                reason = "-"
                for _ in range(200):  # until a full window is judged (at most 100 s wall)
                    await asyncio.sleep(0.5)
                    res = gw.store.results[0]
                    if res is not None and res.samples >= 475:
                        reason = res.assessment.reason
                        break
                client = AsyncModbusTcpClient("127.0.0.1", port=gw.result_port, timeout=2)
                assert await client.connect()
                rsp = await client.read_input_registers(0, count=20, device_id=1)
                client.close()
                assert not rsp.isError()
                assert gw.metrics_port is not None
                text = await asyncio.to_thread(scrape, gw.metrics_port)
                return rsp.registers, text, reason

    regs, text, reason = run(go(), 150)
    r = np.array(regs, dtype=np.uint16)
    assert int(r[0]) == VERDICT_CODES["stiction"], reason
    assert MEASURED in reason
    jump = decode_registers(r[10:12], "float32")[0]
    assert jump / 100.0 == pytest.approx(SLIP, rel=0.10)
    samples = {(s.name, s.labels.get("loop")): s.value
               for fam in text_string_to_metric_families(text) for s in fam.samples}
    assert samples[("stiction_loop_band_ratio", "FIC101")] == pytest.approx(BAND, rel=0.10)
    assert samples[("stiction_loop_position_quality", "FIC101")] == 0.0
