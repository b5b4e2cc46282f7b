"""The state file's version 2 carries the valve's position (a third signal of the windows
of loops that read one); a version 1 file, written before the position existed, restores
as it did (``data/state-v1.npz``: written by the gateway at verdicts 7839f18, one loop A of a
memory device, 40 samples and a stiction assessment)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
from memory_harness import mconfig, mloop

from gateway.config import parse_config
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup, WindowBank
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import read_state, restore_state
from gateway.outputs.statefile.format import snapshot, write_state
from stiction import Verdict

V1 = Path(__file__).parent / "data" / "state-v1.npz"
T0 = 1_700_000_000.0


def _groups(position: bool) -> tuple[Any, list[LoopGroup], ResultStore]:
    extra = {"position": {"column": 2}} if position else {}
    row = [1.0, 2.0, 3.0] if position else [1.0, 2.0]  # the device of data/state-v1.npz
    raw = mconfig([memory_device("plc", [row], poll_interval_s=0.1)],
                  [mloop("A", "plc", 0, 0, **extra)])
    cfg = parse_config(raw, "t")
    bank = WindowBank(["A"], cfg.window_samples(cfg.loops[0]), position=position)
    zero = np.zeros(1, dtype=np.intp)
    pos = zero + 2 if position else None
    return cfg, [LoopGroup("plc", bank, cfg.loops, zero, zero + 1, zero, 0.1, pos)], \
        ResultStore(["A"])


def test_a_version_1_file_restores_window_and_assessment(tmp_path: Path) -> None:
    path = tmp_path / "gw.state"
    shutil.copy(V1, path)
    header, _arrays = read_state(path)
    assert header["version"] == 1
    cfg, banks, store = _groups(position=False)
    report = restore_state(path, cfg, banks, store, wall=T0 + 4.0, time_scale=1.0)
    assert report.restored_windows == 1
    assert report.restored_results == 1
    _t, op, pv, _q = banks[0].bank.series([0])
    assert op[0][:40].tolist() == [40.0 + k for k in range(40)]
    assert pv[0][:40].tolist() == [2.0 * k for k in range(40)]
    res = store.results[0]
    assert res is not None
    assert res.assessment.verdict == Verdict.STICTION
    assert res.assessment.reason == "stiction, from a version 1 file"


def test_a_version_1_file_and_a_loop_given_a_position_since(tmp_path: Path) -> None:
    """The window signature holds the position: the loop starts its window afresh."""
    path = tmp_path / "gw.state"
    shutil.copy(V1, path)
    cfg, banks, store = _groups(position=True)
    report = restore_state(path, cfg, banks, store, wall=T0 + 4.0, time_scale=1.0)
    assert report.fresh == ["A"]
    assert banks[0].bank.count == 0


def test_version_2_carries_the_position(tmp_path: Path) -> None:
    path = tmp_path / "gw.state"
    cfg, banks, store = _groups(position=True)
    for k in range(30):
        pos = np.array([np.nan if k == 7 else 10.0 + k])
        banks[0].bank.append(T0 + 0.1 * k, np.array([1.0]), np.array([2.0]),
                             np.zeros(1, dtype=np.uint8), pos)
    write_state(path, *snapshot(cfg, banks, store, wall=T0 + 3.0, proc=T0 + 3.0))
    header, arrays = read_state(path)
    assert header["version"] == 2
    assert header["banks"][0]["position"] is True
    assert arrays["b0_pos"].shape == (30, 1)
    cfg2, banks2, store2 = _groups(position=True)
    report = restore_state(path, cfg2, banks2, store2, wall=T0 + 3.0, time_scale=1.0)
    assert report.restored_windows == 1
    pos = banks2[0].bank.positions([0])
    assert pos is not None
    want = [np.nan if k == 7 else 10.0 + k for k in range(30)]
    np.testing.assert_array_equal(pos[0][:30], np.array(want, dtype=np.float32))


def test_a_bank_without_positions_writes_none(tmp_path: Path) -> None:
    path = tmp_path / "gw.state"
    cfg, banks, store = _groups(position=False)
    banks[0].bank.append(T0, np.array([1.0]), np.array([2.0]), np.zeros(1, dtype=np.uint8))
    write_state(path, *snapshot(cfg, banks, store, wall=T0, proc=T0))
    header, arrays = read_state(path)
    assert "position" not in header["banks"][0]
    assert "b0_pos" not in arrays
