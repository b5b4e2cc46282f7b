"""Every read of an outside file bounded in time and kind (issue 38 item 3): a findings path
on a hung network mount (a read that never returns stands in) or a FIFO blocked a reload
forever, holding its lock: later SIGHUPs were never applied, SIGTERM waited on it. Now the
read gives up after its time limit with a clear line, the findings read before are kept
and the reload, and the next one, complete. (The real process: tests/e2e/test_fifo_files.py.)"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from memory_harness import FAKE, mconfig, mloop
from prometheus_client import CollectorRegistry

from gateway.config import parse_config, reading
from gateway.config.findings import read_findings
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import read_for_restore
from gateway.runtime.gateway import Gateway


@pytest.fixture
def hung(monkeypatch: pytest.MonkeyPatch) -> Any:
    """Reads of files named ``hung*`` never return (until the test ends); the time limit
    is 0.3 s."""
    release = threading.Event()
    real = reading._read

    def read(path: Any, limit: int) -> bytes:
        if Path(path).name.startswith("hung"):
            release.wait()
            raise OSError(errno.EIO, "released")
        return real(path, limit)

    monkeypatch.setattr(reading, "_read", read)
    monkeypatch.setattr(reading, "READ_TIMEOUT_S", 0.3)
    yield release
    release.set()
    deadline = time.monotonic() + 30  # the abandoned reads end: the next test starts clean
    while reading._pending and time.monotonic() < deadline:
        time.sleep(0.01)


def test_a_read_that_never_returns_gives_up_and_too_many_are_refused(hung: Any) -> None:
    f = read_findings("hung.csv", ["A"], today=__import__("datetime").date(2024, 3, 5))
    assert not f.readable
    assert f.problems == ("hung.csv: cannot read: no answer from the file system in 0.3 s "
                          "(a hung network mount?); not read",)
    while reading._pending < reading.MAX_PENDING:  # more reads of the hung mount
        with pytest.raises(OSError, match="no answer from the file system"):
            reading.read_bytes("hung2.csv", 10)
    with pytest.raises(OSError, match="earlier reads have not returned") as refused:
        reading.read_bytes("hung3.csv", 10, timeout_s=30.0)
    assert refused.value.errno == errno.EBUSY
    assert all(t.daemon for t in threading.enumerate() if t.name == "bounded read")
    hung.set()


def test_a_fifo_is_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "findings.csv"
    os.mkfifo(fifo)
    f = read_findings(fifo, ["A"], today=__import__("datetime").date(2024, 3, 5),
                      shown_as="findings.csv")
    assert f.problems == ("findings.csv: cannot read: is a FIFO (named pipe), not a file: "
                          "name a file",)
    state = tmp_path / "gw.state"
    os.mkfifo(state)
    got = read_for_restore(state, [])
    assert got is not None and not isinstance(got, tuple)
    assert got.kind == "unreadable" and "FIFO" in str(got)


def _config(tmp_path: Path, findings: str) -> Any:
    raw = mconfig([memory_device("plc", [[50.0, 20.0]] * 20, poll_interval_s=0.05,
                                 repeat=True)],
                  [mloop("A", "plc", 0, 0, window_s=1.0)],
                  state_file=str(tmp_path / "gw.state"), persist_interval_s=3600)
    raw["findings"] = findings
    return parse_config(raw, str(tmp_path / "gw.yaml"))


def test_a_reload_with_a_hung_findings_file_completes_and_keeps_the_findings(
        tmp_path: Path, hung: Any, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    good = tmp_path / "findings.csv"
    good.write_text("loop,date,finding\nA,2024-03-05,stiction\n")
    registry = CollectorRegistry()

    async def go() -> None:
        gw = Gateway(_config(tmp_path, str(good)), registry=registry, analyze=FAKE,
                     serve_http=False, persist=True, executor=lambda: ThreadPoolExecutor(1))
        async with gw:
            assert len(gw.findings.findings) == 1
            for _ in range(2):  # the lock is free again: the second reload runs too
                ok = await asyncio.wait_for(gw.reload(_config(tmp_path, str(tmp_path /
                                                                         "hung.csv"))), 10)
                assert ok
            assert gw.reloads == 2
            assert len(gw.findings.findings) == 1  # kept
            assert registry.get_sample_value("stiction_findings_problems") == 1.0

    asyncio.run(asyncio.wait_for(go(), 60))
    assert "no answer from the file system in 0.3 s" in caplog.text
    assert "keeping the 1 finding(s) read before" in caplog.text
