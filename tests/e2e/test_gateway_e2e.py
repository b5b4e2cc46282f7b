"""End to end: plc-sim → gateway (real stiction.analyze in worker processes) → a Modbus
client reads the result registers and an HTTP client reads /metrics.

The demo's loops run at 160x real time for 18.5 s of wall time (2960 process s: every window
full, the level loop's 2400 s too; on a window still holding the simulation's start-up the
learned decision leaves the level valve `undetermined`, as the demo shows in its first
minute).
Checked: every loop's verdict, fd within 10 % for the sticky loops, and that the Modbus
registers and the metrics say the same thing. The simulated PLC serves each valve's position
and the written gateway config reads it (issue 30): the sticky loops are decided from the
valve's travel, their band (metrics) and slip (the jump register) within 10 % of the
simulated valve's (He's model, fs 0.30, fd 0.27, K 1.99: band 2 fs - J = 0.540, slip
J = K (fs - fd) = 0.0597)."""

from __future__ import annotations

import asyncio
import math

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
from plcsim.demo import DEMO_LOOPS, demo_configs
from stiction.diagnosis.travel import MEASURED

pytestmark = [pytest.mark.e2e, pytest.mark.slow, pytest.mark.timing]

WALL_S = 18.5
TIME_SCALE = 160.0
TRUE_FD = {"FIC101": 0.27, "LIC201": 0.27}  # fraction of span, the scenarios' valves
EXPECTED = {
    "FIC101": {"stiction"},
    "LIC201": {"stiction"},
    # a healthy loop with measurement noise: no oscillation (the analysis may also call
    # the noise "too short to see", bad_data; warming_up while its window fills) - never
    # stiction
    "TIC301": {"not_oscillating", "warming_up", "bad_data", "no_stiction"},  # its valve
    # follows OP (read from its position) where OP/PV cannot tell
    "FIC401": {"no_stiction", "undetermined", "not_oscillating", "warming_up"},
    "PIC501": {"no_stiction", "undetermined"},
}


def test_plc_sim_to_gateway_to_modbus_and_metrics() -> None:
    sim_raw, gw_raw = demo_configs(time_scale=TIME_SCALE, metrics_port=0, result_port=0)
    sim_cfg = parse_sim_config(sim_raw)

    async def go() -> tuple[dict[str, list[int]], str, dict[str, str]]:
        async with PlcSim(sim_cfg) as sim:
            gw_raw["devices"][0]["port"] = sim.port
            gateway = Gateway(parse_config(gw_raw, "<e2e>"))
            gateway.align_polls(sim.mid_step())
            async with gateway as gw:
                await asyncio.sleep(WALL_S)
                # freeze the results while both outputs are read: stop the analysis task
                for task in gw._tasks:
                    if task.get_name() == "analysis":
                        task.cancel()
                        await asyncio.wait([task])
                client = AsyncModbusTcpClient("127.0.0.1", port=gw.result_port, timeout=2)
                assert await client.connect()
                blocks = {}
                for lp in gw.config.loops:
                    rsp = await client.read_input_registers(lp.result_address, count=20,
                                                            device_id=1)
                    assert not rsp.isError()
                    blocks[lp.name] = rsp.registers
                client.close()
                assert gw.metrics_port is not None
                text = await asyncio.to_thread(scrape, gw.metrics_port)
                reasons = {n: (r.assessment.reason if r else "-")
                           for n, r in zip(gw.store.loops, gw.store.results, strict=True)}
                # the demo's plant (issue 21): the sticky valve's group holds its followers,
                # and no other loop is named its source (with the shape network U2.FIC101's
                # own window reads 0.2-0.6 in these short windows, undetermined, so the
                # group may name no source: issue 36's figures, docs/accuracy.md)
                (group,) = [g for g in gw.store.plant.groups
                            if {"U2.TIC201", "U2.LIC301"} <= set(g.loops)]
                assert group.source in ("U2.FIC101", None), group
                # (almost) every simulated sample read once: at most 1 % of polls missed
                assert gw.pollers[0].missed_ticks <= 0.01 * gw.pollers[0].polls
                return blocks, text, reasons

    blocks, text, reasons = run(go(), 120)
    samples: dict[tuple[str, tuple[tuple[str, str], ...]], float] = {}
    for fam in text_string_to_metric_families(text):
        for s in fam.samples:
            samples[(s.name, tuple(sorted(s.labels.items())))] = s.value

    def metric(name: str, **labels: str) -> float | None:
        return samples.get((name, tuple(sorted(labels.items()))))

    code_names = {v: k for k, v in VERDICT_CODES.items()}
    assert {n for n, *_ in DEMO_LOOPS} <= set(blocks)
    for name, regs in blocks.items():
        r = np.array(regs, dtype=np.uint16)
        verdict = code_names[int(r[0])]
        if name.startswith("U2."):  # the plant: its source and followers, checked above
            continue
        assert verdict in EXPECTED[name], f"{name}: {verdict} ({reasons[name]})"
        si, fd, fs, period, jump = decode_registers(r[2:12], "float32")
        fill = decode_registers(r[14:16], "float32")[0]
        t = decode_registers(r[12:14], "uint32")[0]
        assert r[1] >= 5  # sequence number: several rounds ran
        # the two outputs agree
        assert metric("stiction_loop_verdict", loop=name, verdict=verdict) == 1.0
        for other in ("stiction", "no_stiction", "undetermined", "not_oscillating",
                      "warming_up", "bad_data", "none", "stale"):
            if other != verdict:
                assert metric("stiction_loop_verdict", loop=name, verdict=other) == 0.0
        assert metric("stiction_loop_last_assessment_timestamp_seconds", loop=name) == \
            pytest.approx(t, abs=1.0)
        assert metric("stiction_loop_window_fill_ratio", loop=name) == pytest.approx(fill)
        for reg, m in ((si, "stiction_index"), (period, "oscillation_period_seconds")):
            got = metric(f"stiction_loop_{m}", loop=name)
            if math.isnan(reg):
                assert got is None
            else:
                assert got == pytest.approx(reg, rel=1e-6)
        for reg, m in ((fd, "fd_ratio"), (fs, "fs_ratio"), (jump, "jump_ratio")):
            got = metric(f"stiction_loop_{m}", loop=name)
            if math.isnan(reg):
                assert got is None
            else:
                assert got == pytest.approx(reg / 100.0, rel=1e-6)
        if name in TRUE_FD:
            assert fd / 100.0 == pytest.approx(TRUE_FD[name], rel=0.10), name
            assert fs / 100.0 == pytest.approx(0.30, rel=0.10), name
            assert MEASURED in reasons[name], reasons[name]
            assert jump / 100.0 == pytest.approx(1.99 * 0.03, rel=0.10), name
            assert metric("stiction_loop_band_ratio", loop=name) == pytest.approx(
                0.60 - 1.99 * 0.03, rel=0.10), name
            assert metric("stiction_loop_position_quality", loop=name) == 0.0
        else:
            assert math.isnan(fd)
    assert metric("stiction_device_up", device="plc-sim") == 1.0
    assert metric("stiction_poll_errors_total", device="plc-sim", kind="timeout") == 0.0
    polls = metric("stiction_poll_duration_seconds_count", device="plc-sim")
    assert polls is not None
    assert polls >= 0.9 * WALL_S * TIME_SCALE  # a poll per process second
    assert metric("stiction_poll_requests_total", device="plc-sim") == polls  # 20 regs: 1
