"""The write schedule the state file and the verdict history share
(gateway.outputs.base.PeriodicWrites): writes only when changed, one line when writes start
failing and one when they work again, a last write at stop that never raises."""

from __future__ import annotations

import asyncio
import logging

import pytest

from gateway.outputs.base import PeriodicWrites

log = logging.getLogger("gateway.test-writes")


def _schedule(outcomes: list[bool], changed: list[bool]) -> tuple[PeriodicWrites, dict]:
    seen: dict = {"saves": [], "failed": 0}

    async def save(**final: object) -> int:
        seen["saves"].append(final)
        if outcomes and not outcomes.pop(0):
            raise OSError(28, "No space left on device")
        return 10

    def failed() -> None:
        seen["failed"] += 1

    writes = PeriodicWrites("test file", lambda: "/x/test", save, lambda: 0.01, log=log,
                            changed=lambda: changed.pop(0) if changed else True,
                            failed=failed)
    return writes, seen


def test_failing_writes_are_logged_once_and_once_when_they_work_again(
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway.test-writes")
    # unchanged twice (no write), three failures, then writes that work
    writes, seen = _schedule([False, False, False, True, True], [False, False])

    async def go() -> None:
        writes.start()
        assert writes.running
        while len(seen["saves"]) < 5:  # noqa: ASYNC110 - nothing to wait on but a list
            await asyncio.sleep(0.005)
        await writes.stop(final=True)

    asyncio.run(go())
    assert not writes.running
    assert seen["failed"] == 3
    assert seen["saves"][-1] == {"final": True} and seen["saves"][0] == {}
    lines = [r.getMessage() for r in caplog.records]
    errors = [m for m in lines if "write failed" in m]
    assert errors == ["test file /x/test: write failed: [Errno 28] No space left on device "
                      "(retrying every 0.01 s)"]
    assert lines.count("test file /x/test: writing again") == 1


def test_stop_writes_once_more_and_never_raises(caplog: pytest.LogCaptureFixture) -> None:
    writes, seen = _schedule([], [])

    async def never_started() -> None:
        await writes.stop()

    asyncio.run(never_started())
    assert seen["saves"] == []  # nothing loaded: nothing written over the old file

    writes, seen = _schedule([False], [False] * 1000)  # the final write fails

    async def go() -> None:
        writes.start()
        await asyncio.sleep(0.03)
        await writes.stop(final=True)

    asyncio.run(go())
    assert seen["saves"] == [{"final": True}] and seen["failed"] == 1
    assert any("test file: final write failed" in r.getMessage() for r in caplog.records)
