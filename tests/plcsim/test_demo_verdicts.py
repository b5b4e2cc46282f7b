"""The demo's verdicts hold still (issue 32 item 3): a 90 s demo at its 40x is 3,600 process
seconds, 30 analysis rounds; replayed in memory (``demo_replay``: the demo's simulated PLC
and the gateway's own analysis rounds, verdict hysteresis and plant step, no sockets, no wall
clock), no loop's published verdict goes into or out of ``stiction`` once its window is full, nor
back and forth. Nothing in the demo's
valves or loads changes; on main its sticky level loop went stiction -> undetermined ->
stiction -> undetermined -> stiction, and the plant's weakly cycling loops changed every
round or two."""

from __future__ import annotations

import itertools

import pytest
from demo_replay import replay_demo
from prometheus_client import CollectorRegistry

from gateway.outputs.prometheus.devices import GatewayMetrics
from plcsim.demo import DEMO_ANALYSIS_INTERVAL_S, DEMO_TIME_SCALE

pytestmark = [pytest.mark.slow]

DEMO_WALL_S = 90.0


def test_no_verdict_changes_once_a_window_is_full() -> None:
    metrics = GatewayMetrics(CollectorRegistry())
    process_s = DEMO_WALL_S * DEMO_TIME_SCALE
    rounds, windows = replay_demo(process_s, metrics=metrics)
    assert len(rounds) == round(process_s / DEMO_ANALYSIS_INTERVAL_S)
    changes = {}
    for name, window_s in windows.items():
        full = [r[name][0] for k, r in enumerate(rounds, 1)
                if k * DEMO_ANALYSIS_INTERVAL_S >= window_s]
        assert full, name
        changes[name] = [(a, b) for a, b in itertools.pairwise(full) if a != b]
    # never into or out of the alarm, never back and forth: a loop may settle once between
    # undetermined and no_stiction as its window slides (the shape network's reading of the
    # demo's U2.FIC102 drifts from 0.22 to 0.09 across its band_low, 0.16: issue 36)
    alarm = {n: c for n, c in changes.items() if any("stiction" in pair for pair in c)}
    assert not alarm, rounds
    assert all(len(c) <= 1 for c in changes.values()), changes
    # the verdicts the demo shows (README)
    last = rounds[-1]
    assert last["FIC101"][0] == "stiction"
    assert last["LIC201"][0] == "stiction"
    assert last["TIC301"][0] == "not_oscillating"
    assert last["PIC501"][0] == "no_stiction"
    # the rule was at work: changes held back, none published once judged
    held = metrics.registry.get_sample_value("stiction_verdict_changes_total",
                                             {"outcome": "held_back"})
    assert held is not None and held > 0
