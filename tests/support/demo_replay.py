"""The demo without sockets or wall clock: its simulated PLC stepped in memory, every sample
recorded into the gateway's windows, and the gateway's analysis rounds (the real
``stiction.analyze``, the verdict hysteresis, the plant step) run every
``analysis_interval_s`` of process time, in one thread. What the demo would print, round by
round, at any time scale."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.core.windows import record
from gateway.outputs.prometheus.devices import GatewayMetrics
from gateway.runtime.reload import build_runtime
from gateway.runtime.scheduler import AnalysisScheduler
from plcsim.demo import demo_configs, demo_sim

__all__ = ["replay_demo"]


def replay_demo(process_s: float, *, hysteresis: dict[str, Any] | None = None,
                metrics: GatewayMetrics | None = None
                ) -> tuple[list[dict[str, tuple[str, float | None]]], dict[str, float]]:
    """Per analysis round, each loop's published (verdict, confidence); and each loop's
    window length in process seconds. ``hysteresis``: the config's ``verdict_hysteresis``
    (None: the demo's own)."""
    sim_raw, gw_raw = demo_configs(metrics_port=0, result_port=0)
    if hysteresis is not None:
        gw_raw["verdict_hysteresis"] = hysteresis
    for dev in gw_raw["devices"]:
        dev["port"] = 502  # never connected: the samples are recorded directly
    sim = demo_sim(sim_raw)  # the demo's plant, running before the gateway comes
    config = parse_config(gw_raw, "<demo gateway>")
    rounds: list[dict[str, tuple[str, float | None]]] = []
    names = sim.cfg.loop_names()
    ts = sim.cfg.ts
    interval = config.gateway.analysis_interval_s

    async def go() -> None:  # the runtime's sources want a running loop (never connected)
        runtime = build_runtime(config, wall=0.0)
        groups, store = runtime.groups, runtime.store
        # the device's points in the order the groups index them
        col = {name: i for i, name in enumerate(names)}
        points = max(int(max(g.op_points.max(), g.pv_points.max())) for g in groups) + 1
        where = [(g.op_points[c], g.pv_points[c], col[lc.name])
                 for g in groups for c, lc in enumerate(g.configs)]
        sched = AnalysisScheduler(
            groups, store, interval_wall_s=1e9, executor=lambda: ThreadPoolExecutor(1),
            plant=config.plant, hysteresis=config.hysteresis,
            on_verdict=None if metrics is None else metrics.count_verdict)
        await sched.start()
        try:
            t = 0.0
            steps_per_round = round(interval / ts)
            while t < process_s:
                for _ in range(steps_per_round):
                    values = np.full(points, np.nan)
                    for op_at, pv_at, k in where:
                        values[op_at], values[pv_at] = sim.op[k], sim.pv[k]
                    record(groups, t, values, np.full(points, Quality.GOOD, np.uint8), store)
                    sim.step()
                    t += ts
                await sched.run_round(now=lambda t=t: t)
                rounds.append({name: (store.verdict_name(i),
                                      None if r is None else r.assessment.confidence)
                               for i, (name, r) in enumerate(zip(store.loops, store.results,
                                                                 strict=True))})
        finally:
            await sched.stop()

    asyncio.run(go())
    windows = {lc.name: lc.window_s for lc in config.loops}
    return rounds, windows
