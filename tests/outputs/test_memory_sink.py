"""The memory output, through a running gateway: started, bound (again on reload), shown
every change of the result store, stopped."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

from memory_harness import mconfig, mloop, wiggle
from prometheus_client import CollectorRegistry
from reliability_helpers import FAKE, until

from gateway.config import parse_config
from gateway.config.plugins import OUTPUTS
from gateway.inputs.memory import memory_device
from gateway.outputs.memory import MemorySink
from gateway.runtime.gateway import Gateway


def test_memory_sink_sees_what_the_outputs_see() -> None:
    assert OUTPUTS["memory"] == "gateway.outputs.memory"
    dev = memory_device("plc", wiggle(100, 4), poll_interval_s=0.05, repeat=True)
    one = parse_config(mconfig([dev], [mloop("A", "plc", 0, 0)], analysis_interval_s=0.3))
    two = parse_config(mconfig([dev], [mloop("A", "plc", 0, 0), mloop("B", "plc", 2, 20)],
                               analysis_interval_s=0.3))

    async def go() -> MemorySink:
        async with Gateway(one, registry=CollectorRegistry(), analyze=FAKE, serve_http=False,
                           outputs=["memory"], executor=lambda: ThreadPoolExecutor(1)) as gw:
            sink = gw.sinks["memory"]
            assert isinstance(sink, MemorySink) and sink.started
            await until(lambda: gw.scheduler.rounds >= 1)
            assert await gw.reload(two)
            await until(lambda: gw.scheduler.rounds >= 3)
            assert sink.snapshot().loops == ("A", "B")
        return sink

    sink = asyncio.run(asyncio.wait_for(go(), 30))
    assert sink.stopped and len(sink.bindings) == 2
    assert sink.bindings[1].config is two
    # the fake analysis says not_oscillating; on windows still filling that is warming_up
    assert ("A", "warming_up") in sink.changes and ("B", "warming_up") in sink.changes
