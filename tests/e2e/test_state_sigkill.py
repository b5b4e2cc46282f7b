"""The state file against a real kill: ``stiction-gateway run`` as a process, SIGKILLed; the
file on disk lags the kill by at most one ``persist_interval_s`` (+ one poll), and the next
start restores it."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml
from reliability_helpers import (
    device,
    raw_config,
    sigkill,
    sim_loops,
    start_gateway,
    start_plc_sim,
    stop,
    wait_log,
)

from bench._net import free_port
from gateway.core.points import Quality
from gateway.outputs.statefile import read_state


def _good_rows(state: Path) -> int:
    """Rows of the state file in which every loop's sample is GOOD (0: no file yet)."""
    if not state.exists():
        return 0
    _header, arrays = read_state(state)
    return int((arrays["b0_q"] == Quality.GOOD).all(axis=1).sum())


@pytest.mark.timing
@pytest.mark.timeout(90)
def test_sigkill_loses_at_most_one_persist_interval(tmp_path: Path) -> None:
    interval, poll = 1.0, 0.1
    port = free_port()
    plc = start_plc_sim(tmp_path, port, loops=4, ts=poll)
    state = tmp_path / "gw.state"
    cfg = tmp_path / "gw.yaml"
    raw = raw_config([device("plc", port, poll=poll)], sim_loops(4, window_s=60.0),
                     state_file=str(state), persist_interval_s=interval)
    cfg.write_text(yaml.safe_dump(raw))
    log = tmp_path / "gw.log"
    try:
        gw = start_gateway(cfg, log)
        try:
            wait_log(log, "gateway running")
            deadline = time.monotonic() + 30
            while _good_rows(state) < 20 and time.monotonic() < deadline:
                time.sleep(0.05)  # a few writes (how soon depends on the machine's load) ...
            time.sleep(1.37)  # ... then one more, and kill somewhere between two
            kill_wall = time.time()
            sigkill(gw)
        finally:
            stop(gw)
        _header, arrays = read_state(state)
        last = float(arrays["b0_t"][-1])
        lost = kill_wall - last
        n_good = _good_rows(state)
        print(f"\nSIGKILL: last saved sample {lost:.2f} s before the kill "
              f"(persist_interval_s {interval}, poll {poll}); {n_good} samples in the file")
        assert lost <= interval + poll + 0.3
        assert n_good >= 20
        # the next start restores it
        gw = start_gateway(cfg, log)
        try:
            text = wait_log(log, "restored 4 windows")
        finally:
            assert stop(gw) == 0
        assert "start fresh" in text
        assert not list(tmp_path.glob(".gw.state.tmp-*"))
    finally:
        stop(plc)
