"""Issue 6 item 5: the result server under hostile input.

A gateway (polling a scripted PLC every 100 ms) runs in its own process. Hypothesis
(derandomised, no example database, ``MAX_EXAMPLES`` inputs) throws at its result server:
random bytes, MBAP frames with random function codes and payloads and wrong length fields,
truncated frames, reads for wrong unit ids, oversize and out-of-range reads, and well-formed
writes of every kind (FC 5, 6, 15, 16, 22, 23). Every well-formed read for the right unit
must be answered with exactly the registers the store implies; every write with an
exception. Then 50 clients read at once. Throughout: the server stays up and the poller keeps
its schedule, with no poll errors.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import multiprocessing
import struct
import time
from typing import Any

import numpy as np
import pytest
from hostile_support import exchange
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from prometheus_client import CollectorRegistry
from reliability_helpers import FAKE, ScriptedPlc, config, device, feed, lateness, loop

from gateway.runtime.gateway import Gateway
from stiction import Assessment, Verdict

MAX_EXAMPLES = 4000
WRITE_CODES = (5, 6, 15, 16, 22, 23)
N_LOOPS = 6
PERIOD = 0.1
LATENESS_BOUND_S = 0.05  # how late a tick may start while the server is fuzzed


def _gateway_process(conn: Any) -> None:
    """The gateway under attack, in its own process (the attackers are elsewhere too: a
    fuzzer in the same process would steal the GIL from the event loop)."""
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)  # as the CLI does
    asyncio.run(_gateway_main(conn))


async def _gateway_main(conn: Any) -> None:
    loop_ = asyncio.get_running_loop()
    plc = await ScriptedPlc(4 * N_LOOPS).start()

    def wiggle(k: int, p: ScriptedPlc) -> None:
        for i in range(N_LOOPS):
            p.set(4 * i, 50.0 + np.sin(k / 5.0 + i))
            p.set(4 * i + 2, 20.0 + np.cos(k / 7.0 + i))

    feeder = asyncio.create_task(feed(plc, 0.02, wiggle))
    loops = [loop(f"L{i}", "plc", 4 * i, 20 * i) for i in range(N_LOOPS)]
    cfg = config([device("plc", plc.port, poll=PERIOD)], loops)
    async with Gateway(cfg, registry=CollectorRegistry(), analyze=FAKE,
                       serve_http=False) as gw:
        for i in range(N_LOOPS):
            gw.store.set_result(i, Assessment(
                Verdict.STICTION, "test", oscillating=True, period_s=100.0 + i,
                stiction_index=0.8, fd=0.1 * i, fs=0.12 * i, jump=0.02),
                t=1.7e9 + i, window_fill=0.5, samples=100)
        await asyncio.sleep(0.5)
        conn.send((gw.result_port, gw.result_server.image.copy()))
        await loop_.run_in_executor(None, conn.recv)  # "begin"
        poller = gw.pollers[0]
        first, missed0 = len(poller.tick_starts), poller.missed_ticks
        await loop_.run_in_executor(None, conn.recv)  # "end"
        errors = sum(gw.registry.get_sample_value("stiction_poll_errors_total",
                                                  {"device": "plc", "kind": k}) or 0
                     for k in ("connect", "timeout", "exception", "protocol"))
        stats = {"starts": poller.tick_starts[first:],
                 "missed": poller.missed_ticks - missed0, "errors": errors,
                 "stale": bool(gw.store.stale.any()),
                 "refused": gw.result_server.server.refused_writes,
                 "image": gw.result_server.image.copy()}
    feeder.cancel()
    await plc.stop()
    conn.send(stats)


def _frame(tid: int, unit: int, pdu: bytes, length: int | None = None) -> bytes:
    n = len(pdu) + 1 if length is None else length
    return struct.pack(">HHHB", tid, 0, n & 0xFFFF, unit) + pdu


u16 = st.integers(0, 0xFFFF)
reads = st.tuples(st.sampled_from([3, 4]), st.integers(0, 140), st.integers(1, 125))
oversize = st.tuples(st.sampled_from([3, 4]), u16, st.integers(126, 0xFFFF))
writes = st.sampled_from(WRITE_CODES).flatmap(lambda fc: st.tuples(
    st.just(fc), u16, st.binary(min_size=0, max_size=40)))


def _write_pdu(fc: int, addr: int, body: bytes) -> bytes:
    if fc in (5, 6):
        return struct.pack(">BHH", fc, addr, 0xFF00 if fc == 5 else 1234)
    if fc == 15:
        return struct.pack(">BHHB", fc, addr, 8 * max(1, len(body)), len(body)) + body
    if fc == 16:
        regs = body[: len(body) // 2 * 2] or b"\x00\x01"
        return struct.pack(">BHHB", fc, addr, len(regs) // 2, len(regs)) + regs
    if fc == 22:
        return struct.pack(">BHHH", fc, addr, 0x00F2, 0x0025)
    regs = body[: len(body) // 2 * 2] or b"\x00\x01"  # FC 23: read 1, write some
    return struct.pack(">BHHHHB", fc, addr, 1, addr, len(regs) // 2, len(regs)) + regs


inputs = st.one_of(
    st.tuples(st.just("bytes"), st.binary(min_size=0, max_size=300)),
    st.tuples(st.just("frame"), st.tuples(u16, st.integers(0, 255), st.integers(0, 255),
                                          st.binary(max_size=260),
                                          st.one_of(st.none(), u16))),
    st.tuples(st.just("truncated"), st.tuples(reads, st.integers(0, 11))),
    st.tuples(st.just("read"), reads),
    st.tuples(st.just("wrong_unit"), st.tuples(reads, st.integers(2, 255))),
    st.tuples(st.just("oversize"), oversize),
    st.tuples(st.just("write"), writes),
)


@pytest.mark.timing
@pytest.mark.timeout(180)
def test_result_server_survives_hostile_input() -> None:
    ctx = multiprocessing.get_context("spawn")
    conn, child_conn = ctx.Pipe()
    proc = ctx.Process(target=_gateway_process, args=(child_conn,))
    proc.start()
    try:
        assert conn.poll(60), "the gateway process did not start"
        port, image = conn.recv()
    except BaseException:
        proc.kill()
        raise
    tried: dict[str, int] = {}
    checked = {"reads": 0, "refused_writes": 0}
    conn.send("begin")
    t0 = time.monotonic()

    @settings(max_examples=MAX_EXAMPLES, derandomize=True, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(inputs)
    def fuzz(case: tuple[str, Any]) -> None:
        kind, arg = case
        tried[kind] = tried.get(kind, 0) + 1
        if kind == "bytes":
            exchange(port, arg, 2.0, want_reply=False)
        elif kind == "frame":
            tid, unit, fc, body, length = arg
            exchange(port, _frame(tid, unit, bytes([fc]) + body, length), 2.0, want_reply=False)
        elif kind == "truncated":
            (fc, addr, count), cut = arg
            data = _frame(7, 1, struct.pack(">BHH", fc, addr, count))
            exchange(port, data[:cut], 2.0, want_reply=False)
        elif kind == "read":
            fc, addr, count = arg
            reply = exchange(port, _frame(9, 1, struct.pack(">BHH", fc, addr, count)), 2.0)
            assert reply[:2] == b"\x00\x09" and reply[6] == 1
            if addr + count <= len(image):
                assert reply[7] == fc and reply[8] == 2 * count, reply
                regs = np.frombuffer(reply[9:], dtype=">u2")
                np.testing.assert_array_equal(regs, image[addr:addr + count])
                checked["reads"] += 1
            else:
                assert reply[7:9] == bytes([fc | 0x80, 2]), reply  # illegal address
        elif kind == "wrong_unit":
            (fc, addr, count), unit = arg
            reply = exchange(port, _frame(5, unit, struct.pack(">BHH", fc, addr, count)),
                             2.0)
            assert reply[7] == fc | 0x80, reply  # an exception, never data
        elif kind == "oversize":
            fc, addr, count = arg
            exchange(port, _frame(3, 1, struct.pack(">BHH", fc, addr, count)), 2.0,
                     want_reply=False)
        else:
            fc, addr, body = arg
            reply = exchange(port, _frame(11, 1, _write_pdu(fc, addr, body)), 2.0)
            if reply:
                assert reply[7] == fc | 0x80, (fc, reply)  # refused
                checked["refused_writes"] += 1

    try:
        fuzz()
        fuzz_s = time.monotonic() - t0
        # many clients at once, every one must get the right registers
        def client(_: int) -> bool:
            reply = exchange(port, _frame(1, 1, struct.pack(">BHH", 3, 0, 20 * N_LOOPS)),
                             limit_s=10)
            regs = np.frombuffer(reply[9:], dtype=">u2")
            return bool(np.array_equal(regs, image[:20 * N_LOOPS]))

        with concurrent.futures.ThreadPoolExecutor(50) as pool:
            ok = list(pool.map(client, range(200)))
        conn.send("end")
        assert conn.poll(30)
        stats = conn.recv()
    finally:
        proc.join(30)
        if proc.is_alive():
            proc.kill()
    starts = stats["starts"]
    late, skipped = lateness(starts, PERIOD)
    missed, errors, stale = stats["missed"], stats["errors"], stats["stale"]
    refused_at_server = stats["refused"]
    total = sum(tried.values())
    print(f"\nfuzz: {total} inputs in {fuzz_s:.1f} s ({tried}); {checked['reads']} reads "
          f"checked, {checked['refused_writes']} writes refused ({refused_at_server} at the "
          f"server); 200 reads by 50 concurrent clients; poller {len(starts)} ticks, "
          f"lateness max {late.max() * 1e3:.1f} ms, missed {missed}, errors {errors}")
    assert total == MAX_EXAMPLES
    assert all(tried.get(k, 0) >= 50 for k in ("bytes", "frame", "read", "write"))
    assert checked["reads"] >= 50 and checked["refused_writes"] >= 50
    assert all(ok)
    assert proc.exitcode == 0  # the gateway shut down cleanly afterwards
    np.testing.assert_array_equal(stats["image"], image)  # nothing was written
    assert errors == 0 and missed == 0 and skipped.sum() == 0 and not stale
    assert float(late.max()) < LATENESS_BOUND_S
