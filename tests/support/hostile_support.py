"""Helpers of the hostile-input tests (tests/test_hostile.py) and ``python -m bench hostile``:
hostile files, half-open connections, raw Modbus frames, processes."""

from __future__ import annotations

import contextlib
import itertools
import os
import socket
import struct
import time
from pathlib import Path
from typing import Any

import yaml
from memory_harness import mconfig, mloop, wiggle

from gateway.inputs.memory import memory_device


def anchor_bomb(levels: int, width: int = 10) -> str:
    """YAML whose last anchor expands to ``width ** levels`` scalars in a few lines (the
    red team's: 9 levels of 9)."""
    names = [f"l{k}" for k in range(levels)]
    lines = [f"{names[0]}: &{names[0]} [{', '.join(['x'] * width)}]"]
    for prev, name in itertools.pairwise(names):
        lines.append(f"{name}: &{name} [{', '.join([f'*{prev}'] * width)}]")
    return "\n".join(lines) + "\n"


def memory_raw(state: Path | None = None, *, poll: float = 0.05, loops: int = 1,
               **gateway: Any) -> dict[str, Any]:
    """A gateway config on a memory device (no PLC), servers on free loopback ports."""
    extra = {"state_file": str(state)} if state is not None else {}
    return mconfig([memory_device("plc", wiggle(400, 2 * loops), poll_interval_s=poll,
                                  repeat=True)],
                   [mloop(f"L{k}", "plc", 2 * k, 20 * k) for k in range(loops)],
                   **extra, **gateway)


def write_yaml(path: Path, data: dict[str, Any], *, header: str = "") -> Path:
    path.write_text(header + yaml.safe_dump(data, sort_keys=False))
    return path


def half_open(port: int, n: int, host: str = "127.0.0.1") -> list[socket.socket]:
    """``n`` TCP connections that never send a byte (each may be refused or reset later)."""
    socks = []
    for _ in range(n):
        s = socket.socket()
        s.setblocking(False)
        with contextlib.suppress(BlockingIOError, InterruptedError):
            s.connect((host, port))
        socks.append(s)
    return socks


def closed_by_peer(socks: list[socket.socket]) -> int:
    """How many of ``socks`` the other end has closed (EOF or reset)."""
    n = 0
    for s in socks:
        try:
            if s.recv(1) == b"":
                n += 1
        except BlockingIOError:
            pass
        except OSError:
            n += 1
    return n


def close_all(socks: list[socket.socket]) -> None:
    for s in socks:
        with contextlib.suppress(OSError):
            s.close()


def frame(tid: int, unit: int, pdu: bytes) -> bytes:
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def exchange(port: int, data: bytes, limit_s: float = 3.0, *, want_reply: bool = True
             ) -> bytes:
    """Send ``data`` and return one Modbus TCP answer (b"" if the server closed, or at once
    without ``want_reply``)."""
    with socket.create_connection(("127.0.0.1", port), timeout=limit_s) as s:
        s.sendall(data)
        if not want_reply:
            return b""
        reply = b""
        while len(reply) < 7 or len(reply) < 6 + struct.unpack(">H", reply[4:6])[0]:
            chunk = s.recv(4096)
            if not chunk:
                break
            reply += chunk
        return reply


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie waiting to be reaped does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (Linux /proc)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        with contextlib.suppress(OSError):
            kids = [int(c) for c in Path(f"/proc/{p}/task/{p}/children").read_text().split()]
            out.extend(kids)
            todo.extend(kids)
    return out


def wait_gone(pids: list[int], limit_s: float) -> list[int]:
    """The processes of ``pids`` still running after ``limit_s`` seconds."""
    deadline = time.monotonic() + limit_s
    left = list(pids)
    while left and time.monotonic() < deadline:
        left = [p for p in left if alive(p)]
        time.sleep(0.05)
    return [p for p in left if alive(p)]


def kill_all(pids: list[int]) -> None:
    for p in pids:
        with contextlib.suppress(OSError):
            os.kill(p, 9)
