"""systemd notify datagrams and reconnect backoff."""

from __future__ import annotations

import random
import socket
from pathlib import Path

import pytest

from gateway.core.ticks import Backoff
from gateway.runtime.sdnotify import Notifier, watchdog_interval


@pytest.fixture
def notify_socket(tmp_path: Path):  # type: ignore[no-untyped-def]
    path = tmp_path / "notify.sock"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(path))
    sock.settimeout(2.0)
    yield path, sock
    sock.close()


def test_notifier_sends_the_protocol_lines(notify_socket) -> None:  # type: ignore[no-untyped-def]
    path, sock = notify_socket
    n = Notifier(str(path))
    assert n.enabled
    assert n.ready("polling 3 devices")
    assert sock.recv(4096) == b"READY=1\nSTATUS=polling 3 devices"
    assert n.watchdog()
    assert sock.recv(4096) == b"WATCHDOG=1"
    assert n.reloading()
    msg = sock.recv(4096).decode()
    assert msg.startswith("RELOADING=1\nMONOTONIC_USEC=")
    assert int(msg.rsplit("=", 1)[1]) > 0
    assert n.stopping()
    assert sock.recv(4096) == b"STOPPING=1"
    n.close()


def test_abstract_namespace_address() -> None:
    name = f"stiction-test-{random.getrandbits(32)}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind("\0" + name)
    sock.settimeout(2.0)
    try:
        assert Notifier("@" + name).watchdog()
        assert sock.recv(100) == b"WATCHDOG=1"
    finally:
        sock.close()


def test_without_systemd_every_call_is_a_no_op(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    n = Notifier()
    assert not n.enabled
    assert not n.ready()
    assert not n.watchdog()


def test_vanished_socket_is_not_fatal(tmp_path: Path) -> None:
    n = Notifier(str(tmp_path / "gone.sock"))
    assert not n.ready()


def test_watchdog_interval(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WATCHDOG_USEC", "10000000")
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    assert watchdog_interval() == 5.0
    monkeypatch.setenv("WATCHDOG_PID", "1")  # another process's watchdog
    assert watchdog_interval() is None
    monkeypatch.delenv("WATCHDOG_USEC")
    assert watchdog_interval() is None


def test_backoff_is_capped_jittered_and_resets() -> None:
    b = Backoff(base=0.5, factor=2.0, cap=8.0, rng=random.Random(1))
    ceilings = []
    delays = []
    for _ in range(12):
        ceilings.append(b.ceiling())
        delays.append(b.next_delay())
    assert ceilings[:5] == [0.5, 1.0, 2.0, 4.0, 8.0]
    assert max(ceilings) == 8.0
    assert all(0 <= d <= c for d, c in zip(delays, ceilings, strict=True))
    assert len(set(delays)) == len(delays)  # jittered, not lock-step
    b.reset()
    assert b.ceiling() == 0.5


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"base": 0}, "`base` must be > 0"),
    ({"factor": 0.5}, "`factor` must be >= 1"),
    ({"base": 2.0, "cap": 1.0}, "`cap` must be >= base"),
])
def test_backoff_validates(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Backoff(**kwargs)
