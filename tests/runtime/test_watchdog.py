"""The systemd watchdog ping, in memory with a fake clock: WATCHDOG=1 while every poller
makes progress, nothing while one is stalled (so systemd restarts a gateway whose polling
hangs), and pings again when it moves; one log line each way."""

from __future__ import annotations

import logging
from typing import Any

import pytest
from memory_harness import mconfig, mloop, wiggle

from gateway.config import parse_config
from gateway.inputs.memory import memory_device
from gateway.runtime.gateway import Gateway
from gateway.runtime.service import Watchdog


class Notes:
    def __init__(self) -> None:
        self.pings = 0

    def watchdog(self) -> bool:
        self.pings += 1
        return True


def test_watchdog_pings_only_while_polls_progress(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gateway")
    devs = [memory_device(n, wiggle(5, 2), poll_interval_s=0.05) for n in ("a", "b")]
    gw = Gateway(parse_config(mconfig(devs, [mloop("A", "a", 0, 0), mloop("B", "b", 0, 20)]),
                              "<watchdog>"), serve_http=False)
    for p in gw.pollers:
        p.guard_s = 0.1  # stalled after period + 2 x guard + 1 s = 1.25 s without a tick
    notes = Notes()
    dog = Watchdog(gw, notes)  # type: ignore[arg-type]
    pinged: list[Any] = []

    def at(now: float, a_last: float | None, b_last: float | None) -> None:
        gw.pollers[0].last_progress, gw.pollers[1].last_progress = a_last, b_last
        pinged.append(dog.step(now))

    at(0.0, None, None)  # before the first tick: not stalled
    at(1.0, 0.95, 0.96)
    at(2.0, 0.95, 1.96)  # a: 1.05 s without a tick: still fine
    at(2.3, 0.95, 2.26)  # a: 1.35 s: stalled
    at(2.4, 0.95, 2.36)
    at(2.5, 2.45, 2.46)  # a moves again
    assert pinged == [True, True, True, False, False, True]
    assert notes.pings == 4
    lines = [r.getMessage() for r in caplog.records]
    assert lines == ["polling stalled for a; withholding the watchdog ping",
                     "polling progresses again; watchdog pings resumed"]
