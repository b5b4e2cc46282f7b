"""A held verdict carries its true age and does not outlive its valve (issue 35 item 5).

On 5c94178 restarts faster than a window fills kept republishing the last verdict, each
restart's first round saying it was "last judged" then (with a fresh time register), for
ever; and after a loop's OP/PV addresses were corrected by a reload, the verdict computed
from the wrong registers came back "held since ...". Now the round that judged a verdict
survives restarts (the state file keeps it), is published (the extended block's +20 and
+22, ``stiction_loop_judged_timestamp_seconds``, ``stiction_loop_verdict_hold``), a hold
ends one window after that round, and a loop whose window (or config) changed starts fresh,
its hold included. The gateway's own scheduler, state file and result server; the fake
analysis calls a swinging OP sticky."""

from __future__ import annotations

import asyncio
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from memory_harness import FAKE, FakeTime, Harness, mconfig, mloop

from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.outputs.prometheus import StoreCollector
from gateway.outputs.statefile import StateFile
from gateway.runtime.scheduler import AnalysisScheduler
from gateway.wire.results import VERDICT_CODES, decode_block

W0 = 1_772_344_800.0  # 2026-03-01 06:00:00 UTC
SWING = [[50.0 + (15.0 if k % 10 < 5 else -15.0), 20.0, 50.0, 20.0] for k in range(100)]


def _raw(tmp_path: Any, *, extended: bool = False, columns: tuple[int, int] = (0, 1)
         ) -> dict[str, Any]:
    loop = mloop("A", "plc", 0, 0, window_s=10.0)  # 200 samples at 0.05 s
    loop["op"], loop["pv"] = {"column": columns[0]}, {"column": columns[1]}
    raw = mconfig([memory_device("plc", SWING, poll_interval_s=0.05, repeat=True)], [loop],
                  state_file=str(tmp_path / "gw.state"))
    if extended:
        raw["modbus_server"]["block_registers"] = 32
    return raw


def _scheduler(h: Harness) -> AnalysisScheduler:
    return AnalysisScheduler(h.runtime.groups, h.store, interval_wall_s=1e9, analyze=FAKE,
                             executor=lambda: ThreadPoolExecutor(1))


async def _round(h: Harness, sched: AnalysisScheduler) -> Any:
    await sched.run_round(now=lambda: h.time.wall)
    res = h.store.results[0]
    assert res is not None
    return res


def _restarts(tmp_path: Any, extended: bool) -> list[tuple[Any, Harness]]:
    """Judged at W0 on a full window, then restarts every 3 s (1 s down, 2 s of polls: 40
    samples, fewer than the 64 a judgement needs): each restart's result and harness."""
    raw = _raw(tmp_path, extended=extended)
    out = []

    async def go() -> None:
        h = Harness(parse_config(raw, "gw.yaml"), time=FakeTime(wall=W0 - 11.0))
        await h.tick(220)
        sched = _scheduler(h)
        await sched.start()
        out.append((await _round(h, sched), h))
        await sched.stop()
        await StateFile(h.runtime.binding(), wall=lambda: h.time.wall).save(final=True)
        for _ in range(5):
            h.time.advance(1.0)  # down
            h = Harness(parse_config(raw, "gw.yaml"), time=h.time)
            h.registry.register(StoreCollector(h.store))
            sink = StateFile(h.runtime.binding(), wall=lambda h=h: h.time.wall)
            await sink.start()  # restores the result and the round that judged it
            await h.tick(40)
            sched = _scheduler(h)
            await sched.start()
            out.append((await _round(h, sched), h))
            await sched.stop()
            await sink.stop()

    asyncio.run(go())
    return out


def _clock(t: float) -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(t))


def test_restarts_faster_than_a_window_fills_keep_the_verdicts_true_age(tmp_path: Any) -> None:
    rounds = _restarts(tmp_path, extended=False)
    first, _h = rounds[0]
    assert str(first.assessment.verdict) == "stiction" and abs(first.t - W0) < 1e-3
    w0 = first.t
    held = [r for r, _h in rounds[1:] if str(r.assessment.verdict) == "stiction"]
    # the restarts 3, 6 and 9 s after the judgement hold it (the window is 10 s), each
    # saying it was judged at W0, not at the restart
    assert len(held) == 3 and [r for r, _h in rounds[1:4]] == held
    for res in held:
        assert res.assessment.reason.startswith("held since ")
        assert f"last judged {_clock(w0)}: warming up" in res.assessment.reason
        assert res.judged_at == w0 and res.hold == 2
        assert res.t > w0 + 2.0  # the round's own time (+12), as every result's
    # at 12 s and 15 s the hold is over: warming up
    rest = [r for r, _h in rounds[3:]]
    for res in rest[1:]:
        assert str(res.assessment.verdict) == "warming_up", res.assessment.reason
    assert rest[1].assessment.reason.startswith(
        f"no longer held: stiction was judged {_clock(w0)}, longer ago than the loop's "
        "window (10 s)")


def test_the_age_is_in_a_register_and_a_metric(tmp_path: Any) -> None:
    rounds = _restarts(tmp_path, extended=True)
    w0 = rounds[0][0].t
    for res, h in rounds[1:3]:
        block = decode_block(h.registers()[0:32])
        assert block["code"] == VERDICT_CODES["stiction"]
        assert block["judged"] == int(w0) and block["hold"] == 2
        assert block["timestamp"] == int(res.t) > int(w0)
        assert h.metric("stiction_loop_judged_timestamp_seconds", loop="A") == w0
        assert h.metric("stiction_loop_verdict_hold", loop="A") == 2.0
    res, h = rounds[-1]
    block = decode_block(h.registers()[0:32])
    assert block["code"] == VERDICT_CODES["warming_up"] and block["hold"] == 0
    assert block["judged"] == block["timestamp"] == int(res.t)


def test_corrected_addresses_start_fresh_their_hold_included(tmp_path: Any) -> None:
    """Judged sticky from the wrong registers (OP read from the swinging column), then the
    addresses corrected by a reload: the next rounds warm up on the new window and never
    bring the old verdict back as "held"."""
    wrong = parse_config(_raw(tmp_path), "gw.yaml")
    right = parse_config(_raw(tmp_path, columns=(2, 3)), "gw.yaml")

    async def go() -> list[Any]:
        h = Harness(wrong, time=FakeTime(wall=W0))
        await h.tick(220)
        sched = _scheduler(h)
        await sched.start()
        out = [await _round(h, sched)]
        h2 = Harness(right, old=h)
        sched.reconfigure(h2.runtime.groups, h2.store, right)
        for _ in range(3):
            await h2.tick(20)
            out.append(await _round(h2, sched))
        await sched.stop()
        return out

    first, *after = asyncio.run(go())
    assert str(first.assessment.verdict) == "stiction"
    for res in after:
        assert str(res.assessment.verdict) == "warming_up"
        assert not res.assessment.reason.startswith("held"), res.assessment.reason
        assert res.hold == 0
