"""PLC faults are contained, in memory, on the real schedule.

Five devices polled by one gateway every 100 ms:

* ``live``    - a healthy PLC, the control group;
* ``refused`` - cannot be reached (every connect fails);
* ``silent``  - connects, but every read times out after 0.3 s;
* ``flaky``   - healthy, then unreachable mid-run, then back;
* ``partial`` - answers, but one block fails (a Modbus exception) until it answers again.

Asserted: exactly the loops fed by a failed device or block go stale (verdict code 6 in the
result registers, ``stiction_loop_verdict{verdict="stale"}`` 1; those of a device that is
down ``device_down``, code 9), the rest do not; the
gateway reconnects with capped backoff; one log line per device when it goes down and one
when it recovers (likewise per failing block); and the live device keeps its schedule: its
tick start times deviate from the ideal absolute schedule by at most ``LATENESS_BOUND_S``.
(The rules poll by poll: tests/runtime/test_poller.py; the Modbus source against refused,
silent and vanishing servers: tests/inputs/modbus/test_modbus_source.py.)
"""

from __future__ import annotations

import asyncio
import logging
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from memory_harness import mconfig, mloop, wiggle
from prometheus_client import CollectorRegistry
from reliability_helpers import lateness

from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.runtime.gateway import Gateway

LATENESS_BOUND_S = 0.050  # a dead or silent device may delay a live one's ticks by this much
PERIOD = 0.1
CAP = 0.5  # gateway.reconnect_max_s
STALE = 6
DOWN = 9  # device_down: stale because the device is down


@pytest.mark.timing
@pytest.mark.timeout(60)
def test_plc_faults_are_contained(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="gateway")
    names = ("live", "refused", "silent", "flaky", "partial")
    devs = [memory_device(n, wiggle(100, 4), poll_interval_s=PERIOD, repeat=True)
            for n in names]
    for d in devs:
        d["timeout_s"] = 0.3
    loops = [mloop("LIVE1", "live", 0, 0), mloop("DEAD1", "refused", 0, 20),
             mloop("MUTE1", "silent", 0, 40), mloop("FLAKY1", "flaky", 0, 60),
             mloop("PART_OK", "partial", 0, 80), mloop("PART_EXC", "partial", 2, 100)]
    cfg = parse_config(mconfig(devs, loops, reconnect_max_s=CAP), "<faults>")
    out: dict[str, object] = {}

    def codes(gw: Gateway) -> dict[str, int]:
        image = gw.result_server.images[1]
        return {lp.name: int(image[lp.result_address]) for lp in gw.config.loops}

    async def go() -> None:
        reg = CollectorRegistry()
        async with Gateway(cfg, registry=reg, serve_http=False,
                           executor=lambda: ThreadPoolExecutor(1)) as gw:
            src = {p.device.name: p.source for p in gw.pollers}
            src["refused"].down = "connect"  # type: ignore[attr-defined]
            src["silent"].silent = True  # type: ignore[attr-defined]
            src["silent"].hang_s = 0.3  # type: ignore[attr-defined]
            src["partial"].failing_blocks = {"holding 200+4": [2, 3]}  # type: ignore[attr-defined]
            await asyncio.sleep(1.0)
            out["codes_1"] = codes(gw)
            out["stale_metric_1"] = {n: reg.get_sample_value(
                "stiction_loop_verdict", {"loop": n, "verdict": "stale"}) for n in codes(gw)}
            src["flaky"].down = "connect"  # type: ignore[attr-defined]  # goes away mid-run
            await asyncio.sleep(1.0)
            out["codes_2"] = codes(gw)
            out["up_2"] = {n: reg.get_sample_value("stiction_device_up", {"device": n})
                           for n in names}
            src["flaky"].down = None  # type: ignore[attr-defined]  # ... and comes back
            src["partial"].failing_blocks = {}  # type: ignore[attr-defined]
            await asyncio.sleep(1.2)
            out["codes_3"] = codes(gw)
            out["tasks_alive"] = all(not t.done() for t in gw._polls.tasks.values())
            p = {x.device.name: x for x in gw.pollers}
            out["live_starts"] = list(p["live"].tick_starts)
            out["live_missed"] = p["live"].missed_ticks
            out["polls"] = {n: x.polls for n, x in p.items()}
            out["connects"] = {n: s.connects for n, s in src.items()}  # type: ignore[attr-defined]
            out["flaky_reconnects"] = p["flaky"].reconnects
            out["errors"] = {(d, k): reg.get_sample_value(
                "stiction_poll_errors_total", {"device": d, "kind": k})
                for d in ("refused", "silent", "partial")
                for k in ("connect", "timeout", "exception")}
            out["ceilings"] = {n: x.backoff.ceiling() for n, x in p.items()}

    t0 = time.monotonic()
    asyncio.run(asyncio.wait_for(go(), 50))
    elapsed = time.monotonic() - t0

    c1, c2, c3 = out["codes_1"], out["codes_2"], out["codes_3"]
    # only the loops fed by a failed device or block are stale (no analysis ran yet: 0);
    # those of a device that is down read device_down (one device alert, not one per loop)
    assert c1 == {"LIVE1": 0, "DEAD1": DOWN, "MUTE1": DOWN, "FLAKY1": 0, "PART_OK": 0,
                  "PART_EXC": STALE}
    assert out["stale_metric_1"] == {"LIVE1": 0, "DEAD1": 0, "MUTE1": 0, "FLAKY1": 0,
                                     "PART_OK": 0, "PART_EXC": 1}
    assert c2 == {**c1, "FLAKY1": DOWN}  # type: ignore[dict-item]
    assert out["up_2"] == {"live": 1, "refused": 0, "silent": 0, "flaky": 0, "partial": 1}
    assert c3 == {"LIVE1": 0, "DEAD1": DOWN, "MUTE1": DOWN, "FLAKY1": 0, "PART_OK": 0,
                  "PART_EXC": 0}
    assert out["tasks_alive"]

    # reconnects forever, with backoff: several attempts, fewer than ticks; capped
    polls, errs, connects = out["polls"], out["errors"], out["connects"]
    assert isinstance(polls, dict) and isinstance(errs, dict) and isinstance(connects, dict)
    assert 4 <= errs[("refused", "connect")] < polls["refused"] * 0.8
    assert errs[("silent", "timeout")] >= 3
    assert connects["silent"] >= 3  # it kept coming back to the silent device
    assert errs[("partial", "exception")] >= 10  # one per poll while the block failed
    assert errs[("partial", "connect")] == errs[("partial", "timeout")] == 0
    assert out["flaky_reconnects"] >= 1
    assert all(c <= CAP for c in out["ceilings"].values())  # type: ignore[attr-defined]

    # one line down, one line recovered, per device and per failing block
    lines = [r.getMessage() for r in caplog.records if r.name == "gateway.poller"]

    def count(dev: str, what: str) -> int:
        return sum(1 for m in lines if m.startswith(f"device {dev}:") and what in m)

    assert count("refused", "down") == 1
    assert count("silent", "down") == 1
    assert count("flaky", "down") == 1
    assert count("flaky", "recovered") == 1
    assert count("partial", "exception code 2; its points are gaps") == 1
    assert count("partial", "answering again") == 1
    assert count("live", "") == 0
    assert count("refused", "") == 1 and count("silent", "") == 1  # never recovered
    assert count("flaky", "") == 2 and count("partial", "") == 2

    # the live device kept its schedule while the others failed
    late, skipped = lateness(out["live_starts"], PERIOD)  # type: ignore[arg-type]
    p99, worst = float(np.percentile(late, 99)), float(late.max())
    print(f"\nlive device: {len(late)} ticks, lateness p99 {p99 * 1e3:.1f} ms, "
          f"max {worst * 1e3:.1f} ms (bound {LATENESS_BOUND_S * 1e3:.0f} ms); "
          f"missed ticks {out['live_missed']}; test {elapsed:.1f} s")
    assert out["live_missed"] == 0 and skipped.sum() == 0
    assert len(late) >= 30
    assert worst < LATENESS_BOUND_S
