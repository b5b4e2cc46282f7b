"""check-config's memory count against what ``run`` allocates (issue 38 item 4), both
measured with tracemalloc on one config: two devices, a window bank in which one loop of 60
reads the valve's position (the bank then holds a position for all 60) and one without.

On 5c94178 the count left the positions out (one ``position:`` in a bank of 2,000 loops:
62.1 MiB counted, 89.5 MiB used) and a state write held three times the windows (a
chronological copy, then a transposed one), so a config accepted under the budget could
pass ``MemoryMax=`` at its first write. Now: the windows are counted exactly as allocated,
a state write and a restore each hold one copy of them (and a chunk of the file), and the
analysis' copies in flight are what :func:`analysis_copy_bytes` says."""

from __future__ import annotations

import pickle
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from memory_harness import mconfig, mloop

from gateway.config import parse_config
from gateway.config.checks import analysis_copy_bytes, memory_bytes, window_bytes
from gateway.core.jobs import batches
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile.format import snapshot, write_state
from gateway.outputs.statefile.restore import apply_state, read_for_restore
from gateway.runtime.reload import build_runtime

SLACK = 3 * 2**20  # the file's header and the pieces a write or a read holds (1 MiB each)


def _config(tmp_path: Path) -> Any:
    devs = [memory_device(name, [[50.0, 20.0, 50.0]], poll_interval_s=1.0, repeat=True)
            for name in ("a", "b")]
    loops = [mloop(f"A{k}", "a", 0, 20 * k, window_s=10_000.0) for k in range(60)]
    loops += [mloop(f"B{k}", "b", 0, 20 * (60 + k), window_s=5_000.0) for k in range(40)]
    loops[7]["position"] = {"column": 2}
    raw = mconfig(devs, loops, state_file=str(tmp_path / "gw.state"))
    raw["gateway"]["analysis_workers"] = 1
    return parse_config(raw, str(tmp_path / "gw.yaml"))


def _peak(fn: Callable[[], Any]) -> tuple[int, Any]:
    """What ``fn`` allocated at its peak, and its result."""
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    out = fn()
    return tracemalloc.get_traced_memory()[1] - before, out


def _fill(groups: Any) -> None:
    rng = np.random.default_rng(0)
    for g in groups:
        b = g.bank
        b.op[:] = rng.normal(50, 5, b.op.shape)
        b.pv[:] = rng.normal(20, 2, b.pv.shape)
        if b.position is not None:
            b.position[:] = b.op
        b.quality[:] = 0
        b.t[:] = np.arange(b.size, dtype=np.float64)
        b.count, b.head = b.size, 1234


def test_the_count_is_what_run_allocates(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    parts = memory_bytes(cfg)
    tracemalloc.start()
    try:
        built, rt = _peak(lambda: build_runtime(cfg, wall=time.time()))
        banks = sum(g.bank.nbytes for g in rt.groups)
        # the windows, exactly: 60 x 10,000 x 13 (positions for all 60) + 40 x 5,000 x 9
        assert window_bytes(cfg) == parts["windows"] == banks == 7_800_000 + 1_800_000 \
            + 8 * 15_000
        assert banks <= built <= banks + SLACK
        _fill(rt.groups)

        def write() -> int:
            header, arrays = snapshot(cfg, rt.groups, rt.store, wall=time.time(), proc=0.0)
            return write_state(tmp_path / "gw.state", header, arrays)

        wrote, _size = _peak(write)
        fresh = build_runtime(cfg, wall=time.time())

        def restore() -> int:
            read = read_for_restore(tmp_path / "gw.state", fresh.groups)
            report = apply_state(read, tmp_path / "gw.state", cfg, fresh.groups, fresh.store,
                                 wall=time.time(), time_scale=1.0)
            return report.restored_windows

        restored, n = _peak(restore)
        assert n == 100
        for g, h in zip(rt.groups, fresh.groups, strict=True):
            assert np.array_equal(g.bank.rows()[1], h.bank.rows()[1])

        def analysis() -> int:
            jobs = []
            for batch in batches(rt.groups, 64):  # the two batches one worker has in flight
                jobs.append((batch, pickle.dumps(batch)))
                if len(jobs) == 2:
                    break
            return len(jobs)

        copied, _n = _peak(analysis)
    finally:
        tracemalloc.stop()
    # one copy of the windows at a state write and at a restore, never two or three
    for measured in (wrote, restored):
        assert banks <= measured + SLACK and measured <= parts["copy"] + SLACK, (
            measured, parts)
    assert analysis_copy_bytes(cfg) == parts["analysis"]
    assert 0.9 * parts["analysis"] <= copied <= parts["analysis"] + SLACK, (copied, parts)
