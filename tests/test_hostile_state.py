"""Issue 22, findings 5 and 6: the state file is untrusted input, and its writes are
watched. Each test failed on main the day the issue was filed (cc81e67).

5. a crafted state file (a sequence number of 2**70, a save time of -1e308, a string in an
   assessment field, a zip bomb) stopped the gateway from starting (OverflowError, exit 1,
   a crash loop), made every scrape fail silently, or took 1.6 GiB before it was set
   aside; 6. failed state writes were one ERROR line and no metric.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import shutil
import time
import tracemalloc
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from memory_harness import FAKE, Harness, mconfig, mloop, wiggle
from prometheus_client import CollectorRegistry, generate_latest
from reliability_helpers import until

from bench.attacks._attacks import rewrite_state
from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import StateFile
from gateway.runtime.gateway import Gateway

POLL = 0.05


def _raw(state: Path, **gateway: Any) -> dict[str, Any]:
    return mconfig([memory_device("plc", wiggle(400, 4), poll_interval_s=POLL, repeat=True)],
                   [mloop("A", "plc", 0, 0), mloop("B", "plc", 2, 20)],
                   state_file=str(state), **gateway)


def _good_file(state: Path) -> None:
    """A state file as the gateway writes it: windows and an assessment per loop."""
    h = Harness(parse_config(_raw(state), "first"))

    async def go() -> None:
        await h.tick(30)
        h.analyse(FAKE)
        await StateFile(h.runtime.binding(), wall=lambda: h.time.wall).save()

    asyncio.run(go())


def _seq(header: dict[str, Any]) -> None:
    header["banks"][0]["loops"][0]["seq"] = 2**70


def _saved_wall(header: dict[str, Any]) -> None:
    header["saved_wall"] = -1e308


def _number_as_text(header: dict[str, Any]) -> None:
    header["banks"][0]["loops"][0]["result"]["assessment"]["stiction_index"] = "0.93"


def _text(header: dict[str, Any]) -> None:
    header["banks"][0]["loops"][0]["result"]["assessment"]["fd"] = "sticky"


CRAFTED = {"seq 2**70": _seq, "saved_wall -1e308": _saved_wall,
           "a number as a string": _number_as_text, "a string in fd": _text}


@pytest.mark.parametrize("case", sorted(CRAFTED))
@pytest.mark.timeout(60)
def test_a_crafted_state_file_never_stops_the_gateway_from_starting(
        tmp_path: Path, caplog: pytest.LogCaptureFixture, case: str) -> None:
    """Finding 5: the gateway starts, polls and renders every scrape; the file is set aside
    with one log line naming the field, counted in stiction_state_file_set_aside_total
    (main: OverflowError at start, exit 1, or every scrape 500 with no log line)."""
    caplog.set_level(logging.WARNING, logger="gateway")
    state = tmp_path / "gw.state"
    _good_file(state)
    rewrite_state(state, CRAFTED[case])
    out: dict[str, Any] = {}

    async def go() -> None:
        async with Gateway(parse_config(_raw(state), "t"), registry=CollectorRegistry(),
                           analyze=FAKE, serve_http=False, persist=True,
                           executor=lambda: ThreadPoolExecutor(1)) as gw:
            await until(lambda: gw.pollers[0].good_polls >= 3)
            out["page"] = generate_latest(gw.registry).decode()
            out["aside"] = gw.registry.get_sample_value(
                "stiction_state_file_set_aside_total", {"reason": "corrupt"})
            out["results"] = gw.store.results

    asyncio.run(asyncio.wait_for(go(), 50))
    assert "stiction_loop_verdict" in out["page"]
    assert out["aside"] == 1
    assert out["results"] == [None, None]  # started empty
    assert len(list(tmp_path.glob("gw.state.corrupt-*"))) == 1
    lines = [r.getMessage() for r in caplog.records if r.name == "gateway.state"
             and r.levelno >= logging.WARNING]
    assert len(lines) == 1 and "starting fresh" in lines[0], lines
    assert "2**70" not in lines[0] and len(lines[0]) < 600


@pytest.mark.timeout(120)
def test_a_zip_bomb_is_refused_before_it_is_unpacked(tmp_path: Path) -> None:
    """Finding 5: a 1.6 MB file took RSS to 1.6 GiB before main set it aside. A member
    that would unpack to 400 MiB is refused from the sizes the archive declares: the
    restore allocates a few MiB at most (traced), and the windows stay empty."""
    state = tmp_path / "gw.state"
    _good_file(state)
    rewrite_state(state, bomb_bytes=400 * 2**20)
    assert state.stat().st_size < 2 * 2**20
    harness = Harness(parse_config(_raw(state), "t"))
    sink = StateFile(harness.runtime.binding(), wall=lambda: harness.time.wall)
    tracemalloc.start()
    try:
        _restore(sink)
        _current, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 32 * 2**20, peak
    assert sink.report is not None and "would unpack to" in (sink.report.problem or "")
    assert len(list(tmp_path.glob("gw.state.corrupt-*"))) == 1
    assert all(g.bank.count == 0 for g in harness.runtime.groups)


def _restore(sink: StateFile) -> None:
    from gateway.outputs.statefile import restore_state  # noqa: PLC0415

    b = sink.binding
    sink.report = restore_state(sink.path, b.config, b.groups, b.store, wall=time.time(),
                                time_scale=1.0)


# ------------------------------------------------------------------ 6. failed writes


@pytest.mark.timeout(60)
def test_failed_state_writes_are_counted_for_monitoring(tmp_path: Path) -> None:
    """Finding 6: on a full disk main logged one ERROR line and nothing else. Each failed
    write counts in stiction_state_write_failures_total; the last good write's time stays
    in stiction_state_last_write_timestamp_seconds (an alert watches both)."""
    folder = tmp_path / "state"
    state = folder / "gw.state"
    out: dict[str, Any] = {}

    async def go() -> None:
        async with Gateway(parse_config(_raw(state, persist_interval_s=0.1), "t"),
                           registry=CollectorRegistry(), analyze=FAKE, serve_http=False,
                           persist=True, executor=lambda: ThreadPoolExecutor(1)) as gw:
            def value(name: str) -> float:
                return gw.registry.get_sample_value(name) or 0.0

            await until(lambda: value("stiction_state_last_write_timestamp_seconds") > 0)
            shutil.rmtree(folder)
            folder.write_text("the disk is full\n")  # every write fails from now on
            last = value("stiction_state_last_write_timestamp_seconds")
            await until(lambda: value("stiction_state_write_failures_total") >= 3)
            out["last"] = (last, value("stiction_state_last_write_timestamp_seconds"))
            folder.unlink()

    asyncio.run(asyncio.wait_for(go(), 50))
    assert out["last"][0] == out["last"][1] > 0


def test_every_assessment_the_analysis_can_write_passes_the_checks() -> None:
    """The checks follow stiction.Assessment: an assessment with every field set (the
    sample sticky one, and each verdict) passes, so a good file is never set aside."""
    from result_fixtures import STICKY  # noqa: PLC0415

    from gateway.outputs.statefile.validate import check_assessment  # noqa: PLC0415
    from stiction import Assessment, Evidence, Verdict  # noqa: PLC0415

    full = dataclasses.replace(STICKY, warnings=("short window",), multi_jump=True,
                               evidence=(Evidence("si_op", 0.9, 1, "triangles"),))
    check_assessment(full.to_dict(), "a")
    for verdict in Verdict:
        check_assessment(Assessment(verdict, "why").to_dict(), "a")
