"""End to end (issue 21, item 3): the simulated PLC's plant scenario (``sticky-feeds-two``: a
sticky flow valve whose cycle reaches a temperature and a level loop) polled by the gateway
with its real analysis workers, time-accelerated; mbpoll reads every loop's plant registers
(+18 role and group, +19 the source loop's index) and /metrics must say the same group,
role and source. Under CI=true a missing mbpoll fails (deploy_support.require_tool)."""

from __future__ import annotations

import asyncio
import re
import subprocess
import time

import pytest
from deploy_support import require_tool
from gateway_helpers import run, scrape
from prometheus_client.parser import text_string_to_metric_families

from gateway.config import parse_config
from gateway.runtime.gateway import Gateway
from plcsim import PlcSim, gateway_config, parse_sim_config

pytestmark = [pytest.mark.e2e]

TIME_SCALE = 100.0  # 1200 process s of window in 12 s of wall time
WINDOW_S = 1200.0
DEADLINE_S = 60.0  # wall s until the group with its source shows in /metrics


def _mbpoll(mbpoll: str, port: int, address: int) -> tuple[int, int]:
    """Registers +18 and +19 of the block at ``address`` (unit 1, holding registers)."""
    r = subprocess.run([mbpoll, "-m", "tcp", "-p", str(port), "-a", "1", "-0", "-r",
                        str(address + 18), "-c", "2", "-t", "4", "-1", "127.0.0.1"],
                       capture_output=True, text=True, timeout=15, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    values = [int(v) for v in re.findall(r"^\[\d+\]:\s+(-?\d+)", r.stdout, re.M)]
    assert len(values) == 2, r.stdout
    return values[0], values[1]


def _plant_metrics(text: str) -> tuple[dict[str, tuple[int, str]], dict[int, str]]:
    """Per loop (group, role) and per group its source, from /metrics."""
    group: dict[str, int] = {}
    role: dict[str, str] = {}
    sources: dict[int, str] = {}
    for fam in text_string_to_metric_families(text):
        for s in fam.samples:
            if s.name == "stiction_loop_plant_group":
                group[s.labels["loop"]] = int(s.value)
            elif s.name == "stiction_loop_plant_role" and s.value == 1.0:
                role[s.labels["loop"]] = s.labels["role"]
            elif s.name == "stiction_plant_group_loops":
                sources[int(s.labels["group"])] = s.labels["source"]
    return {n: (g, role.get(n, "")) for n, g in group.items()}, sources


def test_mbpoll_and_metrics_agree_on_the_plant_group_role_and_source() -> None:
    mbpoll = require_tool("mbpoll", "mbpoll")
    sim_cfg = parse_sim_config({
        "listen": "127.0.0.1:0", "ts": 1.0, "time_scale": TIME_SCALE, "seed": 3,
        "plants": [{"plant": "sticky-feeds-two", "window_s": WINDOW_S}],
    })
    raw = gateway_config(sim_cfg, analysis_interval_s=120.0, metrics_listen="127.0.0.1:0",
                         result_listen="127.0.0.1:0")

    async def go() -> tuple[str, dict[str, tuple[int, int]], list[str], float]:
        async with PlcSim(sim_cfg) as sim:
            raw["devices"][0]["port"] = sim.port
            gateway = Gateway(parse_config(raw, "<plant e2e>"))
            gateway.align_polls(sim.mid_step())
            async with gateway as gw:
                t0 = time.monotonic()
                assert gw.metrics_port is not None
                while time.monotonic() - t0 < DEADLINE_S:
                    await asyncio.sleep(1.0)
                    g = [g for g in gw.store.plant.groups if g.source == "FIC101"]
                    if g and {"TIC201", "LIC301"} <= set(g[0].loops):
                        break
                found = time.monotonic() - t0
                for task in gw._tasks:  # freeze the results while both outputs are read
                    if task.get_name() == "analysis":
                        task.cancel()
                        await asyncio.wait([task])
                text = await asyncio.to_thread(scrape, gw.metrics_port)
                regs = {lp.name: await asyncio.to_thread(_mbpoll, mbpoll, gw.result_port,
                                                         lp.result_address)
                        for lp in gw.config.loops}
                return text, regs, [lp.name for lp in gw.config.loops], found

    text, regs, order, found = run(go(), DEADLINE_S + 60)
    print(f"group with its source after {found:.1f} s wall; registers {regs}")
    per_loop, sources = _plant_metrics(text)
    # the plant: FIC101's sticky valve is the source, TIC201 and LIC301 follow it
    number, role = per_loop["FIC101"]
    assert number >= 1 and role == "source", (per_loop, sources)
    assert sources[number] == "FIC101"
    assert per_loop["TIC201"] == per_loop["LIC301"] == (number, "follower")
    # mbpoll's registers say the same, loop by loop
    codes = {"": 0, "source": 1, "follower": 2}
    for name, (r18, r19) in regs.items():
        group, its_role = per_loop[name]
        assert (r18 & 0xFF, r18 >> 8) == (group, codes[its_role]), name
        source = sources.get(group, "") if group else ""
        assert r19 == (order.index(source) + 1 if source else 0), name
