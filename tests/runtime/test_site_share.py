"""The gateway's loops as one site (issue 36 item 3): each round the share of sticky valves
the loops' own windows imply (label-shift EM over the shape network's readings) moves each
loop's call, its reason saying so; ``analysis.site_adaptation: false`` scores each loop
alone. Driven by hand: memory devices, the real analysis in a thread, a fake clock."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import pytest
from gateway_helpers import run
from memory_harness import Harness, mconfig, mloop

from gateway.config import parse_config
from gateway.runtime.scheduler import AnalysisScheduler
from stiction.scenarios import scenario, simulate

N = 1500
# four sticky valves and one good loop: the site's share far above the simulation's 0.18
LOOPS = [("table4-case2", 1), ("table4-case2", 2), ("table4-case2", 3), ("table4-case2", 4),
         ("aggressive-tuning", 1)]


def _rows() -> list[list[float]]:
    cols: list[np.ndarray] = []
    for name, seed in LOOPS:
        r = simulate(scenario(name), noise=0.02, seed=seed, duration=float(N))
        cols += [r.op[:N], r.pv[:N]]
    return np.column_stack(cols).tolist()


@pytest.fixture(scope="module")
def rows() -> list[list[float]]:
    return _rows()


def _rounds(rows: list[list[float]], **analysis: Any) -> Harness:
    loops = [mloop(f"L{k}", "plc", 2 * k, 20 * k, window_s=N, op_range=[0, 100])
             for k in range(len(LOOPS))]
    raw = mconfig([{"name": "plc", "protocol": "memory", "poll_interval_s": 1.0,
                    "timeout_s": 1.0, "values": rows}], loops)
    if analysis:
        raw["analysis"] = analysis
    h = Harness(parse_config(raw, "gw.yaml"))
    sched = AnalysisScheduler(h.runtime.groups, h.store, interval_wall_s=1e9,
                              analyze="stiction:analyze", plant=h.config.plant,
                              executor=lambda: ThreadPoolExecutor(1),
                              site_adaptation=h.config.analysis.site_adaptation)

    async def go() -> None:
        await h.tick(N)
        await sched.start()
        await sched.run_round()  # no share yet: each loop alone
        await sched.run_round()  # at the share the first round's windows imply
        await sched.stop()

    run(go())
    return h


def test_the_loops_are_called_at_their_sites_share(rows: list[list[float]]) -> None:
    h = _rounds(rows)
    got = [r.assessment for r in h.store.results if r is not None]
    assert len(got) == len(LOOPS)
    shares = {a.site_share for a in got}
    assert {a.site for a in got} == {"adapted"} and len(shares) == 1
    (share,) = shares
    assert share is not None and share > 0.3  # 0.18 in the simulation
    assert all("At this site's share of sticky valves" in a.reason for a in got
               if a.verdict.value in ("stiction", "no_stiction", "undetermined"))
    alone = _rounds(rows, site_adaptation=False)
    for a, b in zip(got, (r.assessment for r in alone.store.results if r is not None),
                    strict=True):
        assert b.site == "none" and b.site_share is None
        assert (a.confidence or 0.0) >= (b.confidence or 0.0) - 1e-9  # a higher share
