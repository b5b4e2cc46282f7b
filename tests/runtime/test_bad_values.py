"""Issue 6 item 2: bad values are quality flags and ``bad_data`` verdicts, never crashes.

A scripted PLC serves six loops, polled every 50 ms (time_scale 20) and analysed by the real
``stiction.analyze`` after 60 samples:

* ``NANL``   OP NaN, PV alternating +inf/-inf;
* ``RANGE``  PV 150 +- noise with the point's ``range: [0, 100]``;
* ``SWAP``   a noisy PV written low word first while the gateway reads big-endian words,
  ``range: [0, 100]``;
* ``SWAP50`` 50.0 word-swapped (a subnormal, caught without any range);
* ``FROZEN`` a PV stuck at 42.0 (sensor frozen) while OP moves;
* ``OK``     a healthy loop, the control group.
"""

from __future__ import annotations

import asyncio
import logging

import numpy as np
import pytest
from prometheus_client import CollectorRegistry
from reliability_helpers import ScriptedPlc, config, device, feed, loop, read_codes, until

from gateway.inputs.base import Quality
from gateway.runtime.gateway import Gateway
from stiction import Verdict, analyze

RNG = np.random.default_rng(3)


def _script(k: int, plc: ScriptedPlc) -> None:
    s = np.sin(k / 4.0)
    plc.set(0, np.nan)
    plc.set(2, np.inf if k % 2 else -np.inf)
    plc.set(10, 50 + 5 * s)
    plc.set(12, 150 + RNG.normal())
    plc.set(20, 50 + 5 * s)
    plc.set(22, 37.3 + RNG.normal(), word_order="little")
    plc.set(30, 50 + 5 * s)
    plc.set(32, 50.0, word_order="little")
    plc.set(40, 50 + 5 * s + RNG.normal(0, 0.5))
    plc.set(42, 42.0)
    plc.set(50, 50 + 5 * s + RNG.normal(0, 0.5))
    plc.set(52, 20 + 2 * np.sin((k - 3) / 4.0) + RNG.normal(0, 0.1))


BAD = ("NANL", "RANGE", "SWAP", "SWAP50")


@pytest.mark.timeout(60)
def test_bad_values_become_flags_and_bad_data(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="gateway")
    out: dict[str, object] = {}
    rng_pv = {"range": [0, 100]}

    async def go() -> None:
        plc = await ScriptedPlc(64).start()
        feeder = asyncio.create_task(feed(plc, 0.02, _script))
        loops = [loop("NANL", "plc", 0, 0, window_s=100),
                 loop("RANGE", "plc", 10, 20, window_s=100),
                 loop("SWAP", "plc", 20, 40, window_s=100),
                 loop("SWAP50", "plc", 30, 60, window_s=100),
                 loop("FROZEN", "plc", 40, 80, window_s=100),
                 loop("OK", "plc", 50, 100, window_s=100)]
        loops[1]["pv"].update(rng_pv)
        loops[2]["pv"].update(rng_pv)
        addrs = {lp["name"]: lp["result_address"] for lp in loops}
        cfg = config([device("plc", plc.port, poll=1.0, timeout=0.5)], loops,
                     time_scale=20.0, analysis_interval_s=60.0)
        async with Gateway(cfg, registry=CollectorRegistry(), serve_http=False) as gw:
            await until(lambda: gw.scheduler.rounds >= 1)
            bank = gw.pollers[0].groups[0].bank
            _t, _op, _pv, q = bank.series(np.arange(len(bank.loops)))
            out["quality"] = dict(zip(bank.loops, q, strict=True))
            out["results"] = {n: gw.store.results[i] for n, i in gw.store.index.items()}
            out["stale"] = gw.store.stale.copy()
            out["codes"] = await read_codes(gw.result_port, addrs)
            out["alive"] = all(not t.done() for t in gw._polls.tasks.values())
        feeder.cancel()
        await plc.stop()

    asyncio.run(asyncio.wait_for(go(), 50))
    assert out["alive"]
    assert not any("unexpectedly" in r.getMessage() for r in caplog.records)
    quality = out["quality"]
    assert isinstance(quality, dict)
    for name in ("NANL", "RANGE", "SWAP50"):
        assert (quality[name] == Quality.BAD).all(), name
    # a word-swapped noisy float is mostly out of range (negative half the time, huge
    # often) or subnormal: about 70 % of samples; the rest are scattered, too few in a row
    assert (quality["SWAP"] == Quality.BAD).mean() > 0.5
    assert (quality["FROZEN"] == Quality.GOOD).all()
    assert (quality["OK"] == Quality.GOOD).all()

    results = out["results"]
    assert isinstance(results, dict)
    for name in BAD:
        a = results[name].assessment
        assert a.verdict == Verdict.BAD_DATA, (name, a)
        assert "bad values" in a.reason, (name, a.reason)
    frozen = results["FROZEN"].assessment
    assert frozen.verdict == Verdict.BAD_DATA
    assert "PV" in frozen.reason and ("constant" in frozen.reason or "frozen" in frozen.reason)
    assert results["OK"].assessment.verdict != Verdict.BAD_DATA
    assert not np.asarray(out["stale"]).any()  # bad values are not stale: the device answers
    assert out["codes"] == {"NANL": 5, "RANGE": 5, "SWAP": 5, "SWAP50": 5, "FROZEN": 5,
                            "OK": out["codes"]["OK"]}  # type: ignore[index]
    assert out["codes"]["OK"] in (1, 2, 3, 4)  # type: ignore[index]
    logged = [r.getMessage() for r in caplog.records if "bad values" in r.getMessage()]
    assert logged and "NANL.op" in logged[0]


def test_analysis_says_why_on_non_finite_and_frozen_windows() -> None:
    """The analysis itself (no gateway): NaN/inf beyond what it interpolates, and a frozen
    PV, give bad_data with a reason."""
    n = 400
    t = np.arange(n)
    op = 50 + 5 * np.sign(np.sin(2 * np.pi * t / 50))
    pv = 20 + np.sin(2 * np.pi * t / 50)
    gappy = pv.copy()
    gappy[100:200] = np.nan
    gappy[300:310] = np.inf
    a = analyze(op, gappy, ts=1.0)
    assert a.verdict == Verdict.BAD_DATA and "gappy" in a.reason
    a = analyze(op, np.full(n, 42.0), ts=1.0)
    assert a.verdict == Verdict.BAD_DATA and "PV" in a.reason
