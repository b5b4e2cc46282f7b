"""The memory input: its config keys, and a source that replays rows and scripts failures."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from memory_harness import mconfig, mloop

from gateway.config import parse_config
from gateway.config.plugins import INPUTS, input_plugin
from gateway.core.points import Quality
from gateway.errors import ConfigError, DeviceError
from gateway.inputs.memory import MemorySource, memory_device
from gateway.runtime.reload import build_runtime

G, B, N = Quality.GOOD, Quality.BAD, Quality.NO_COMM


def test_registered_by_one_line() -> None:
    assert INPUTS["memory"] == "gateway.inputs.memory"
    assert input_plugin("memory") is not None


def test_config_builds_a_source_reading_columns() -> None:
    dev = memory_device("m", [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
                        quality=[[0, 0, 0], [0, 2, 0]])
    cfg = parse_config(mconfig([dev], [{"name": "A", "device": "m", "op": {"column": 2},
                                        "pv": {"column": 1}, "result_address": 0}]))
    src = build_runtime(cfg, wall=0.0).pollers[0].source
    assert isinstance(src, MemorySource)

    async def go() -> list[tuple[list[float], list[int]]]:
        await src.connect()
        reads = [await src.read() for _ in range(3)]
        return [(r.values.tolist(), r.quality.tolist()) for r in reads]

    assert asyncio.run(go()) == [([3.0, 2.0], [G, G]), ([6.0, 5.0], [G, B]),
                                 ([6.0, 5.0], [G, B])]  # after the last row: the last


def test_config_problems() -> None:
    bad = mconfig([memory_device("m", [[1.0, 2.0], [3.0]], quality=[[0, 9]], repeat="yes")],
                  [{"name": "A", "device": "m", "op": {"column": 2}, "pv": {"col": 1},
                    "result_address": 0}])
    with pytest.raises(ConfigError) as info:
        parse_config(bad, "gw.yaml")
    assert info.value.problems == [
        "gw.yaml: device m: key 'values': rows must all have the same length, was "
        "[[1.0, 2.0], [3.0]]",
        "gw.yaml: device m: key 'quality': must hold quality codes 0..4, was [[0, 9]]",
        "gw.yaml: device m: key 'repeat': must be true or false, was 'yes'",
        "gw.yaml: loop A: missing required key 'pv.column'",
        "gw.yaml: loop A: unknown key 'pv.col'",
    ]
    # (with the device invalid, a column is only checked to be a register-like index;
    # with a valid one, against the width of its rows)
    with pytest.raises(ConfigError, match=r"key 'op.column': must be in 0..1, was 2"):
        parse_config(mconfig([memory_device("m", [[1.0, 2.0]])], [
            {"name": "A", "device": "m", "op": {"column": 2}, "pv": {"column": 1},
             "result_address": 0}]))
    with pytest.raises(ConfigError, match=r"key 'quality': must have the shape of 'values'"):
        parse_config(mconfig([memory_device("m", [[1.0, 2.0]], quality=[[0]])],
                             [mloop("A", "m", 0, 0)]))


def test_scripted_failures() -> None:
    src = MemorySource("m", 2, repeat=True)
    src.feed([1.0, 2.0])
    src.feed([3.0, 4.0], [G, N])

    async def go() -> None:
        with pytest.raises(DeviceError, match="not connected"):
            await src.read()
        await src.connect()
        assert (await src.read()).values.tolist() == [3.0, 4.0]  # read 2: row 2
        assert (await src.read()).values.tolist() == [1.0, 2.0]  # repeat: row 1 again
        src.fail_reads = {4: "timeout"}
        with pytest.raises(DeviceError) as info:
            await src.read()
        assert info.value.kind == "timeout" and not src.connected
        await src.connect()
        src.failing_blocks = {"holding 0+2": [1]}
        res = await src.read()
        assert res.quality.tolist() == [G, N] and np.isnan(res.values[1])
        assert [e.kind for e in res.errors] == ["exception"]
        src.down = "auth"
        with pytest.raises(DeviceError) as info:
            await src.connect()
        assert info.value.kind == "auth"
        src.down, src.silent, src.hang_s = None, True, 0.01
        await src.connect()
        with pytest.raises(DeviceError) as info:
            await src.read()
        assert info.value.kind == "timeout"
        await src.close()

    asyncio.run(go())
    assert (src.connects, src.closes) == (4, 1)


def test_no_rows_is_no_communication() -> None:
    src = MemorySource("m", 3)

    async def go() -> None:
        await src.connect()
        res = await src.read()
        assert np.isnan(res.values).all() and (res.quality == N).all()

    asyncio.run(go())
