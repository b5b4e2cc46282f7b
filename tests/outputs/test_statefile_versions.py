"""The state file survives a downgrade and a shorter window (issue 35 item 7). On 5c94178 it
was set aside, windows and verdicts gone and sequence numbers back to 1:

* by the previous release (the one before state file version 2), because version 2 was
  written even where no loop reads a position: now version 1 is written where nothing of
  version 2 is in the file, and the previous release's own reader reads it;
* by a restart with a shorter ``window_s``, because a genuine file of longer windows was
  over the size bound the new windows give: now it is read trimmed to the new windows (the
  newest samples), the rest read past, and the sequence numbers go on."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import tarfile
import time
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from memory_harness import FAKE, Harness, mconfig, mloop

from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import StateFile, read_state
from gateway.outputs.statefile.format import snapshot, state_bounds, write_state
from stiction import Assessment, Verdict

REPO = Path(__file__).resolve().parents[2]
PREVIOUS = "dfc6edc^"  # the release before state file version 2 (positions)
V1 = Path(__file__).resolve().parent / "data" / "state-v1.npz"  # written by that release
V1_ASSESSMENT = {"verdict", "reason", "oscillating", "period_s", "stiction_index", "fd", "fs",
                 "jump", "fd_op", "fs_op", "cycles_used", "multi_jump", "warnings",
                 "confidence", "evidence", "band", "band_op"}  # that release's Assessment


def _raw(state: Path, window_s: float = 10.0, position: bool = False) -> dict[str, Any]:
    loop = mloop("A", "plc", 0, 0, window_s=window_s)
    if position:
        loop["position"] = {"column": 0}
    return mconfig([memory_device("plc", [[50.0, 20.0], [40.0, 21.0]], poll_interval_s=0.05,
                                  repeat=True)],
                   [loop, mloop("B", "plc", 0, 20, window_s=window_s)], state_file=str(state))


def _written(tmp_path: Path, position: bool) -> Path:
    state = tmp_path / f"gw-{position}.state"
    h = Harness(parse_config(_raw(state, position=position), "t"))

    async def go() -> None:
        await h.tick(40)
        h.analyse(FAKE)

    asyncio.run(go())
    write_state(state, *snapshot(h.config, h.runtime.groups, h.store, wall=time.time(),
                                 proc=h.time.wall))
    return state


def _keys(x: Any) -> Any:
    """The structure of a header: its keys, recursively (lists by their first item)."""
    if isinstance(x, dict):
        return {k: _keys(v) for k, v in x.items() if k != "assessment"}
    if isinstance(x, list) and x and isinstance(x[0], dict):
        return [_keys(x[0])]
    return None


def test_version_1_is_written_where_nothing_of_version_2_is_in_it(tmp_path: Path) -> None:
    plain, with_position = _written(tmp_path, False), _written(tmp_path, True)
    header, arrays = read_state(plain)
    assert header["version"] == 1 and not any(k.endswith("_pos") for k in arrays)
    old_header, _ = read_state(V1)  # what the previous release wrote has every key we write
    ours, theirs = _keys(header), _keys(old_header)
    # (what is added is what the previous release ignores: it reads its own keys only)
    assert set(ours) - set(theirs) <= {"order", "plant"}
    assert set(ours["banks"][0]) <= set(theirs["banks"][0])
    entry = header["banks"][0]["loops"][0]
    assert set(entry) <= set(theirs["banks"][0]["loops"][0])
    assert set(entry["result"]) <= {"assessment", "seq", "t", "window_fill", "samples",
                                    "judged", "hold", "pv_swing", "since"}  # (the old reader
        # ignores extra keys)
    assert set(entry["result"]["assessment"]) <= V1_ASSESSMENT
    header2, arrays2 = read_state(with_position)
    assert header2["version"] == 2 and "b0_pos" in arrays2


def _previous_release(tmp_path: Path) -> Path:
    try:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", PREVIOUS, "gateway",
                                  "stiction"], capture_output=True, check=True, timeout=60)
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"no git history for {PREVIOUS} ({exc}): a checkout without it")
    tree = tmp_path / "previous"
    with tarfile.open(fileobj=BytesIO(archive.stdout)) as tar:
        tar.extractall(tree, filter="data")
    return tree


def test_the_previous_release_reads_what_this_one_writes(tmp_path: Path) -> None:
    plain = _written(tmp_path, False)
    tree = _previous_release(tmp_path)
    code = ("import json, sys\nfrom gateway.outputs.statefile.format import read_state\n"
            "h, a = read_state(sys.argv[1])\n"
            "print(json.dumps([h['version'], sorted(a), [e.get('seq') for b in h['banks'] "
            "for e in b['loops']]]))\n")
    out = subprocess.run([sys.executable, "-c", code, str(plain)], capture_output=True, check=False,
                         text=True, cwd=tree, env={"PYTHONPATH": str(tree)}, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    version, members, seqs = json.loads(out.stdout)
    assert version == 1 and "b0_op" in members and seqs == [1, 1]


def test_a_shorter_window_reads_the_newest_samples_of_a_file_over_its_bound(
        tmp_path: Path) -> None:
    state = tmp_path / "gw.state"
    long_s, short_s = 150_000.0, 5_000.0  # samples at 0.05 s: 3,000,000 and 100,000
    first = Harness(parse_config(_raw(state, long_s), "first"))
    (group,) = first.runtime.groups
    bank = group.bank
    rng = np.random.default_rng(1)
    bank.op[:] = rng.normal(50, 5, bank.op.shape)
    bank.pv[:] = rng.normal(20, 2, bank.pv.shape)
    bank.quality[:] = 0
    bank.t[:] = first.time.wall - 0.05 * np.arange(bank.size)[::-1]
    bank.count, bank.head = bank.size, 0
    first.store.set_result(0, Assessment(
        Verdict.STICTION, "sticky"), t=first.time.wall,
        window_fill=1.0, samples=bank.size)
    write_state(state, *snapshot(first.config, first.runtime.groups, first.store,
                                 wall=first.time.wall, proc=first.time.wall, clean=True))
    second = Harness(parse_config(_raw(state, short_s), "second"), time=first.time)
    bound, _loops = state_bounds(second.runtime.groups)
    assert state.stat().st_size > 2 * bound  # a genuine file, far over today's bound
    sink = StateFile(second.runtime.binding(), wall=lambda: second.time.wall)

    async def go() -> None:
        await sink.start()
        await sink.writes.stop()

    asyncio.run(go())
    report = sink.report
    assert report is not None and report.kind is None and report.set_aside is None
    assert report.restored_windows == 2 and not list(tmp_path.glob("gw.state.*-*"))
    (new,) = second.runtime.groups
    n = new.bank.size
    assert n == 100_000 and new.bank.count == n
    t, op, pv, _q, _pos = new.bank.rows()
    np.testing.assert_array_equal(op[:, 0], bank.op[-n:, 0])  # the newest samples
    np.testing.assert_array_equal(pv[:, 1], bank.pv[-n:, 1])
    np.testing.assert_array_equal(t, bank.t[-n:])
    # the sequence numbers go on (the verdict, judged on the longer window, does not)
    assert second.store.last_seq(0) == 1 and second.store.results[0] is None
    second.store.set_result(0, Assessment(
        Verdict.STICTION, "x"), t=1.0, window_fill=1.0, samples=1)
    assert second.store.results[0] is not None and second.store.results[0].seq == 2
