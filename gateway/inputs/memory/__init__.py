"""In-memory input plugin (``protocol: memory``): a device whose values are literal rows.

For tests (reliability rules with literal arrays and a fake clock, golden config cases) and
for trying the outputs without a PLC. Device keys::

    - name: bench
      protocol: memory
      poll_interval_s: 1.0
      timeout_s: 1.0
      values:             # one row per read, one raw value per column (.nan, .inf allowed)
        - [50.0, 20.0, 51.0, 20.5]
        - [52.0, 20.1, 49.0, 20.4]
      quality: [[0, 0, 0, 0], [0, 0, 2, 0]]   # optional, Quality codes, same shape
      repeat: false       # after the last row: start again (true) or keep the last (false)

and a point reads one column: ``op: {column: 0}``. From Python, :class:`MemorySource` also
takes rows with :meth:`~MemorySource.feed` and scripts failures: ``down`` (every connect and
read fails with that kind: a refused or unreachable device), ``silent`` (connects, but every
read fails with a timeout), ``fail_reads`` (read number -> kind), ``failing_blocks`` (a
partial failure: those points NO_COMM with a DeviceError of kind ``exception``),
``refused`` (a reason and a message: every point refused, as by a PLC that does not serve
the unit id) and ``hang_s`` (every read takes that long first).
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...config import schema as s
from ...config.schema import MISSING, Section
from ...core.points import PointSpec, Quality
from ...errors import DeviceError
from ..base import ReadResult

if TYPE_CHECKING:
    from ...config import DeviceConfig

__all__ = ["POINT_ADDRESS_KEY",
           "MemoryOptions", "MemoryPoint", "MemorySource", "create_input", "memory_device",
           "parse_device", "parse_point"]

POINT_ADDRESS_KEY = "column"
"""The point key a tag list's op/pv cell fills (a column; gateway.config.tags)."""


@dataclasses.dataclass(frozen=True)
class MemoryOptions:
    values: tuple[tuple[float, ...], ...]
    quality: tuple[tuple[int, ...], ...] | None = None
    repeat: bool = False


@dataclasses.dataclass(frozen=True)
class MemoryPoint:
    column: int

    def __str__(self) -> str:
        return f"column {self.column}"


def _rows(value: Any) -> tuple[tuple[float, ...], ...]:
    if (not isinstance(value, list) or not value
            or not all(isinstance(r, list) and r for r in value)):
        raise TypeError("must be a non-empty list of non-empty lists of numbers")
    if len({len(r) for r in value}) != 1:
        raise ValueError("rows must all have the same length")
    if not all(isinstance(x, int | float) and not isinstance(x, bool) for r in value for x in r):
        raise TypeError("must hold numbers only")
    return tuple(tuple(float(x) for x in r) for r in value)


def _quality(value: Any) -> tuple[tuple[int, ...], ...]:
    rows = _rows(value)
    codes = {int(q) for q in Quality}
    if not all(not math.isnan(x) and x == int(x) and int(x) in codes for r in rows for x in r):
        raise ValueError(f"must hold quality codes {min(codes)}..{max(codes)}")
    return tuple(tuple(int(x) for x in r) for r in rows)


def _boolean(value: Any) -> bool:
    if not isinstance(value, bool):
        raise TypeError("must be true or false")
    return value


def parse_device(sec: Section) -> MemoryOptions | Any:
    values = sec.req("values", _rows)
    quality = sec.opt("quality", _quality, None)
    repeat = sec.opt("repeat", _boolean, False)
    if MISSING in (values, quality, repeat):
        return MISSING
    if quality is not None and (len(quality), len(quality[0])) != (len(values),
                                                                   len(values[0])):
        sec.error("quality", "must have the shape of 'values'")
        return MISSING
    return MemoryOptions(values, quality, repeat)


def parse_point(sec: Section, options: MemoryOptions | None) -> MemoryPoint | Any:
    width = len(options.values[0]) if options is not None else 65536
    column = sec.req("column", s.integer(0, width - 1))
    return MISSING if column is MISSING else MemoryPoint(column)


def create_input(device: DeviceConfig, points: Sequence[PointSpec], **_: Any) -> MemorySource:
    opts: MemoryOptions = device.options
    columns = [p.address.column for p in points]
    source = MemorySource(device.name, len(points), repeat=opts.repeat)
    for k, row in enumerate(opts.values):
        quality = None if opts.quality is None else np.asarray(opts.quality[k])[columns]
        source.feed(np.asarray(row)[columns], quality)
    return source


class MemorySource:
    """A :class:`~gateway.inputs.base.Source` that replays rows of raw values.

    Read number k (1, 2, ...) returns row k, failed reads included (after the last row:
    the last again, or from the first with ``repeat``); with no rows, every point is NaN
    with quality NO_COMM."""

    def __init__(self, name: str, n_points: int, *, repeat: bool = False,
                 clock: Callable[[], float] = time.time) -> None:
        self.name = name
        self.n_points = n_points
        self.repeat = repeat
        self.clock = clock
        self.rows: list[tuple[NDArray[np.float64], NDArray[np.uint8]]] = []
        self.down: str | None = None  # a DeviceError kind: connect and read fail with it
        self.silent = False  # connect succeeds, reads time out
        self.fail_reads: dict[int, str] = {}  # read number (1, 2, ...) -> kind
        self.failing_blocks: dict[str, Sequence[int]] = {}  # block name -> point indices
        # (reason, message): every read answered, every point refused (an exception)
        self.refused: tuple[str, str] | None = None
        self.hang_s = 0.0
        self.connected = False
        self.connects = self.reads = self.closes = 0

    def feed(self, values: ArrayLike, quality: ArrayLike | None = None) -> None:
        """Queue one row of raw values (and qualities, default GOOD)."""
        v = np.asarray(values, dtype=np.float64).reshape(self.n_points)
        q = (np.full(self.n_points, Quality.GOOD, dtype=np.uint8) if quality is None
             else np.asarray(quality, dtype=np.uint8).reshape(self.n_points))
        self.rows.append((v, q))

    def _fail(self, kind: str, what: str) -> DeviceError:
        return DeviceError(self.name, kind, f"{what} ({kind}, scripted)")

    async def connect(self) -> None:
        self.connects += 1
        if self.down is not None:
            raise self._fail(self.down, "cannot connect")
        self.connected = True

    async def read(self) -> ReadResult:
        t = self.clock()
        if self.hang_s > 0:
            await asyncio.sleep(self.hang_s)
        self.reads += 1
        if not self.connected:
            raise self._fail("connect", "not connected")
        kind = self.down or ("timeout" if self.silent else None) or self.fail_reads.get(self.reads)
        if kind is not None:
            self.connected = False
            raise self._fail(kind, "no answer")
        values, quality = self._row(self.reads)
        errors = []
        for block, points in self.failing_blocks.items():
            values[list(points)] = np.nan
            quality[list(points)] = Quality.NO_COMM
            errors.append(DeviceError(self.name, "exception", f"{block}: exception code 2"))
        if self.refused is not None:
            reason, message = self.refused
            values[:] = np.nan
            quality[:] = Quality.NO_COMM
            errors = [DeviceError(self.name, "exception", message, reason=reason)]
        return ReadResult(t, values, quality, 1, tuple(errors))

    def _row(self, k: int) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
        if not self.rows:
            return (np.full(self.n_points, np.nan),
                    np.full(self.n_points, Quality.NO_COMM, dtype=np.uint8))
        i = (k - 1) % len(self.rows) if self.repeat else min(k, len(self.rows)) - 1
        v, q = self.rows[i]
        return v.copy(), q.copy()

    async def close(self) -> None:
        self.closes += 1
        self.connected = False


def memory_device(name: str, rows: Sequence[Sequence[float]], *, poll_interval_s: float = 1.0,
                  **extra: Any) -> dict[str, Any]:
    """A ``devices:`` entry for a memory device (a YAML-ready dict)."""
    return {"name": name, "protocol": "memory", "poll_interval_s": poll_interval_s,
            "timeout_s": 1.0, "values": [list(r) for r in rows], **extra}

