"""The state file output: atomic writes read back, and files that are not (or no longer)
readable set aside with a warning, never a crash."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from memory_harness import mconfig, mloop

from gateway.config import parse_config
from gateway.core.store import ResultStore
from gateway.core.windows import LoopGroup, WindowBank
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import read_state, restore_state
from gateway.outputs.statefile.format import snapshot, write_state


def _bank() -> tuple[Any, list[LoopGroup], ResultStore]:
    raw = mconfig([memory_device("plc", [[1.0, 2.0]], poll_interval_s=0.1)],
                  [mloop("A", "plc", 0, 0)])
    cfg = parse_config(raw, "t")
    bank = WindowBank(["A"], cfg.window_samples(cfg.loops[0]))
    zero = np.zeros(1, dtype=np.intp)
    return cfg, [LoopGroup("plc", bank, cfg.loops, zero, zero + 1, zero, 0.1)], ResultStore(["A"])


def _good_state(path: Path) -> None:
    cfg, banks, store = _bank()
    for k in range(30):
        banks[0].bank.append(float(k), np.array([1.0]), np.array([2.0]),
                             np.zeros(1, dtype=np.uint8))
    write_state(path, *snapshot(cfg, banks, store, wall=time.time(), proc=time.time()))


def _corrupt(path: Path) -> None:
    path.write_bytes(os.urandom(3000))


def _truncated(path: Path) -> None:
    _good_state(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _foreign(path: Path) -> None:
    with open(path, "wb") as f:
        np.savez(f, weights=np.ones(10))


def _wrong_version(path: Path) -> None:
    with open(path, "wb") as f:
        header = b'{"format": "stiction-gateway-state", "version": 99}'
        np.savez(f, header=np.frombuffer(header, dtype=np.uint8))


def _empty(path: Path) -> None:
    path.write_bytes(b"")


@pytest.mark.parametrize(("make", "kind"), [(_corrupt, "corrupt"), (_truncated, "corrupt"),
                                            (_empty, "corrupt"), (_foreign, "foreign"),
                                            (_wrong_version, "foreign")])
def test_bad_state_files_are_set_aside(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                       make: Any, kind: str) -> None:
    path = tmp_path / "gw.state"
    make(path)
    cfg, banks, store = _bank()
    report = restore_state(path, cfg, banks, store, wall=time.time(), time_scale=1.0)
    assert not path.exists()
    aside = list(tmp_path.glob(f"gw.state.{kind}-*"))
    assert len(aside) == 1 and report.set_aside == aside[0]
    assert banks[0].bank.count == 0 and report.restored_windows == 0
    assert any(r.levelname == "WARNING" and "starting fresh" in r.getMessage()
               for r in caplog.records)


def test_a_written_state_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "state" / "gw.state"
    _good_state(path)
    header, arrays = read_state(path)
    # version 1: no position in it, so the release before version 2 reads it (issue 35 item 7)
    assert header["format"] == "stiction-gateway-state" and header["version"] == 1
    assert [e["name"] for e in header["banks"][0]["loops"]] == ["A"]
    assert arrays["b0_t"].tolist() == [float(k) for k in range(30)]
    assert (arrays["b0_op"] == 1.0).all() and arrays["b0_op"].shape == (30, 1)
    assert not list(path.parent.glob(".gw.state.tmp-*"))  # no temporary file left
