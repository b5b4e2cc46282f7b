"""Issue 6 item 1: PLC faults.

Five devices polled by one gateway, every 100 ms:

* ``live``    - a healthy PLC, the control group;
* ``refused`` - nothing listens on its port (connect refused from the start);
* ``silent``  - accepts TCP, never answers a request;
* ``flaky``   - healthy, then its server goes away mid-run, then comes back;
* ``partial`` - answers one block, but the other (a separate request) with Modbus exception
  2 until the test enlarges its register image.

Asserted: the gateway keeps running and reconnects forever with capped jittered backoff;
exactly the loops fed by a failed device or block go stale (verdict code 6 in the result
registers, ``stiction_loop_verdict{verdict="stale"}`` 1), the rest do not; exactly one log
line per device when it goes down and one when it recovers (likewise per failing block);
and the live device keeps its schedule: its tick start times deviate from the ideal
absolute schedule by at most ``LATENESS_BOUND_S`` (max over every tick, p99 reported).
"""

from __future__ import annotations

import asyncio
import logging
import time

import numpy as np
import pytest
from prometheus_client import CollectorRegistry
from reliability_helpers import (
    ScriptedPlc,
    SilentServer,
    config,
    device,
    feed,
    lateness,
    loop,
    read_codes,
)

from bench._net import free_port
from gateway.runtime.gateway import Gateway

LATENESS_BOUND_S = 0.050  # a dead or silent device may delay a live one's ticks by this much
PERIOD = 0.1
CAP = 0.5  # gateway.reconnect_max_s


def _wiggle(k: int, plc: ScriptedPlc) -> None:
    for a in (0, 200):  # op at a, pv at a + 2
        if a + 4 <= len(plc.image):
            plc.set(a, 50.0 + 10.0 * np.sin(k / 5.0))
            plc.set(a + 2, 20.0 + np.cos(k / 7.0))


@pytest.mark.timeout(60)
def test_plc_faults_are_contained(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="gateway")
    results: dict[str, object] = {}

    async def go() -> None:
        live = await ScriptedPlc(8).start()
        flaky = await ScriptedPlc(8).start()
        partial = await ScriptedPlc(8).start()  # block at 200 beyond the image: exception 2
        feeders = [asyncio.create_task(feed(p, 0.05, _wiggle)) for p in (live, flaky, partial)]
        refused_port = free_port()
        async with SilentServer() as silent:
            devs = [device("live", live.port), device("refused", refused_port),
                    device("silent", silent.port), device("flaky", flaky.port),
                    device("partial", partial.port)]
            loops = [loop("LIVE1", "live", 0, 0), loop("DEAD1", "refused", 0, 20),
                     loop("MUTE1", "silent", 0, 40), loop("FLAKY1", "flaky", 0, 60),
                     loop("PART_OK", "partial", 0, 80), loop("PART_EXC", "partial", 200, 100)]
            addrs = {lp["name"]: lp["result_address"] for lp in loops}
            cfg = config(devs, loops, reconnect_max_s=CAP)
            reg = CollectorRegistry()
            async with Gateway(cfg, registry=reg, serve_http=False) as gw:
                await asyncio.sleep(1.5)
                results["codes_1"] = await read_codes(gw.result_port, addrs)
                results["stale_metric_1"] = {
                    n: reg.get_sample_value("stiction_loop_verdict",
                                            {"loop": n, "verdict": "stale"}) for n in addrs}
                await flaky.stop()  # the device goes away mid-run
                await asyncio.sleep(1.5)
                results["codes_2"] = await read_codes(gw.result_port, addrs)
                results["up_2"] = {d["name"]: reg.get_sample_value(
                    "stiction_device_up", {"device": d["name"]}) for d in devs}
                flaky = ScriptedPlc(8, port=flaky.port)  # ... and comes back on its port
                await flaky.start()
                feeders.append(asyncio.create_task(feed(flaky, 0.05, _wiggle)))
                partial.resize(256)  # the failing block answers again
                await asyncio.sleep(2.0)
                results["codes_3"] = await read_codes(gw.result_port, addrs)
                results["tasks_alive"] = all(not t.done() for t in gw._polls.tasks.values())
                p = {x.device.name: x for x in gw.pollers}
                results["live_starts"] = list(p["live"].tick_starts)
                results["live_missed"] = p["live"].missed_ticks
                results["polls"] = {n: x.polls for n, x in p.items()}
                results["flaky_reconnects"] = p["flaky"].reconnects
                results["silent_connections"] = silent.connections
                results["errors"] = {(d, k): reg.get_sample_value(
                    "stiction_poll_errors_total", {"device": d, "kind": k})
                    for d in ("refused", "silent", "partial")
                    for k in ("connect", "timeout", "exception")}
                results["backoff_ceiling"] = {n: x.backoff.ceiling() for n, x in p.items()}
        for t in feeders:
            t.cancel()
        for plc in (live, flaky, partial):
            await plc.stop()

    t0 = time.monotonic()
    asyncio.run(asyncio.wait_for(go(), 50))
    elapsed = time.monotonic() - t0

    stale = 6
    c1, c2, c3 = results["codes_1"], results["codes_2"], results["codes_3"]
    # only the loops fed by a failed device or block are stale (no analysis ran yet: 0)
    assert c1 == {"LIVE1": 0, "DEAD1": stale, "MUTE1": stale, "FLAKY1": 0, "PART_OK": 0,
                  "PART_EXC": stale}
    assert results["stale_metric_1"] == {"LIVE1": 0, "DEAD1": 1, "MUTE1": 1, "FLAKY1": 0,
                                         "PART_OK": 0, "PART_EXC": 1}
    assert c2 == {**c1, "FLAKY1": stale}
    assert results["up_2"] == {"live": 1, "refused": 0, "silent": 0, "flaky": 0, "partial": 1}
    assert c3 == {"LIVE1": 0, "DEAD1": stale, "MUTE1": stale, "FLAKY1": 0, "PART_OK": 0,
                  "PART_EXC": 0}
    assert results["tasks_alive"]

    # reconnects forever, with backoff: several attempts, fewer than ticks; capped
    polls = results["polls"]
    errs = results["errors"]
    assert errs[("refused", "connect")] >= 4
    assert errs[("refused", "connect")] < polls["refused"] * 0.8
    assert errs[("silent", "timeout")] >= 3
    assert results["silent_connections"] >= 3  # it kept coming back to the silent device
    assert errs[("partial", "exception")] >= 10  # one per poll while the block failed
    assert errs[("partial", "connect")] == errs[("partial", "timeout")] == 0
    assert results["flaky_reconnects"] >= 1
    assert all(c <= CAP for c in results["backoff_ceiling"].values())

    # one line down, one line recovered, per device and per failing block
    lines = [r.getMessage() for r in caplog.records if r.name == "gateway.poller"]

    def count(dev: str, what: str) -> int:
        return sum(1 for m in lines if m.startswith(f"device {dev}:") and what in m)

    assert count("refused", "down") == 1
    assert count("silent", "down") == 1
    assert count("flaky", "down") == 1
    assert count("flaky", "recovered") == 1
    assert count("partial", "exception code 2") == 1
    assert count("partial", "answering again") == 1
    assert count("live", "") == 0
    assert count("refused", "") == 1 and count("silent", "") == 1  # never recovered
    assert count("flaky", "") == 2 and count("partial", "") == 2

    # the live device kept its schedule while the others failed
    late = lateness(results["live_starts"], PERIOD)
    p99, worst = float(np.percentile(late, 99)), float(late.max())
    print(f"\nlive device: {len(late)} ticks, lateness p99 {p99 * 1e3:.1f} ms, "
          f"max {worst * 1e3:.1f} ms (bound {LATENESS_BOUND_S * 1e3:.0f} ms); "
          f"missed ticks {results['live_missed']}; test {elapsed:.1f} s")
    assert results["live_missed"] == 0
    assert len(late) >= 45
    assert worst < LATENESS_BOUND_S
