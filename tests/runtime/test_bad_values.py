"""Bad values are quality flags and ``bad_data`` verdicts, never crashes, in memory.

One memory device serves six loops, polled 100 times (fake clock, 1 s sample time) and
analysed by the real ``stiction.analyze``, inline:

* ``NANL``   OP NaN, PV alternating +inf/-inf;
* ``RANGE``  PV 150 +- noise with the point's ``range: [0, 100]``;
* ``SWAP``   a noisy PV written low word first and read high word first, ``range: [0, 100]``;
* ``SWAP50`` 50.0 word-swapped (a subnormal, caught without any range);
* ``FROZEN`` a PV stuck at 42.0 (sensor frozen) while OP moves;
* ``OK``     a healthy loop, the control group.
"""

from __future__ import annotations

import asyncio
import logging

import numpy as np
import pytest
from memory_harness import Harness, mconfig, mloop

from gateway.config import parse_config
from gateway.core.points import Quality
from gateway.inputs.memory import memory_device
from gateway.wire.codec import decode_registers, encode_values
from stiction import Verdict, analyze

RNG = np.random.default_rng(3)
BAD = ("NANL", "RANGE", "SWAP", "SWAP50")


def _swapped(x: float) -> float:
    """What a gateway reading big-endian words gets from a float written low word first."""
    return float(decode_registers(encode_values([x], "float32", "little"), "float32")[0])


def _row(k: int) -> list[float]:
    s = np.sin(k / 4.0)
    return [np.nan, np.inf if k % 2 else -np.inf,
            50 + 5 * s, 150 + RNG.normal(),
            50 + 5 * s, _swapped(37.3 + RNG.normal()),
            50 + 5 * s, _swapped(50.0),
            50 + 5 * s + RNG.normal(0, 0.5), 42.0,
            50 + 5 * s + RNG.normal(0, 0.5), 20 + 2 * np.sin((k - 3) / 4.0) + RNG.normal(0, 0.1)]


def test_bad_values_become_flags_and_bad_data(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="gateway")
    rows = [[float(x) for x in _row(k)] for k in range(100)]
    loops = [mloop(name, "plc", 2 * i, 20 * i, window_s=100)
             for i, name in enumerate(("NANL", "RANGE", "SWAP", "SWAP50", "FROZEN", "OK"))]
    loops[1]["pv"]["range"] = [0, 100]
    loops[2]["pv"]["range"] = [0, 100]
    h = Harness(parse_config(mconfig([memory_device("plc", rows)], loops), "<bad values>"))
    asyncio.run(h.tick(100))
    assert h.analyse("stiction:analyze") == 6
    quality = {name: h.window(name)[3] for name in h.store.loops}
    for name in ("NANL", "RANGE", "SWAP50"):
        assert (quality[name] == Quality.BAD).all(), name
    # a word-swapped noisy float is mostly out of range (negative half the time, huge
    # often) or subnormal; the rest are scattered, too few in a row
    assert (quality["SWAP"] == Quality.BAD).mean() > 0.5
    assert (quality["FROZEN"] == Quality.GOOD).all()
    assert (quality["OK"] == Quality.GOOD).all()

    results = {n: h.store.results[i] for n, i in h.store.index.items()}
    for name in BAD:
        a = results[name].assessment
        assert a.verdict == Verdict.BAD_DATA, (name, a)
        assert "bad values" in a.reason, (name, a.reason)
    frozen = results["FROZEN"].assessment
    assert frozen.verdict == Verdict.BAD_DATA
    assert "PV" in frozen.reason and ("constant" in frozen.reason or "frozen" in frozen.reason)
    assert results["OK"].assessment.verdict != Verdict.BAD_DATA
    assert not h.store.stale.any()  # bad values are not stale: the device answers
    codes = {name: int(h.block(name)[0]) for name in h.store.loops}
    assert codes == {"NANL": 5, "RANGE": 5, "SWAP": 5, "SWAP50": 5, "FROZEN": 5,
                     "OK": codes["OK"]}
    assert codes["OK"] in (1, 2, 3, 4)
    logged = [r.getMessage() for r in caplog.records if "implausible values" in r.getMessage()]
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
