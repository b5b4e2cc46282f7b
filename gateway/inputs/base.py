"""The interface every protocol adapter implements.

An adapter serves one device (one PLC, one connection). It is built with the device's
config and the ordered list of points (each loop contributes its OP point and its PV point)
and returns, per poll, one value and one quality per point, as numpy arrays in the same
order: no per-sample Python objects, so 10,000 loops cost a few array operations.

A point that could not be read is NaN with a non-GOOD quality: never a zero.
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..errors import DeviceError

__all__ = ["DeviceInput", "PointSpec", "Quality", "ReadResult"]


class Quality(enum.IntEnum):
    """Quality of one sample (stored as uint8 in windows and the state file)."""

    GOOD = 0
    UNCERTAIN = 1  # the source said uncertain (OPC UA) - kept as a gap by analysis
    BAD = 2  # the source said bad, or the value was NaN/inf/out of range
    NO_COMM = 3  # the read failed (device down, timeout, exception for this block)
    MISSING = 4  # no poll happened for this slot (gateway was not running)


@dataclasses.dataclass(frozen=True)
class PointSpec:
    """One value to read. ``address`` is protocol-specific (a Modbus register spec or an
    OPC UA node id); ``scale``/``offset`` map raw to engineering units (value*scale+offset)."""

    loop: str
    role: str  # "op" or "pv"
    address: Any
    scale: float = 1.0
    offset: float = 0.0


@dataclasses.dataclass(frozen=True)
class ReadResult:
    """One poll of one device: ``values`` float64 and ``quality`` uint8, one per point, and
    the wall-clock time (Unix seconds) the poll started. ``requests`` counts protocol
    requests the poll sent. ``errors`` lists partial failures (e.g. a Modbus exception for
    one block) whose points came back NaN/NO_COMM while the rest of the poll succeeded."""

    t: float
    values: NDArray[np.float64]
    quality: NDArray[np.uint8]
    requests: int
    errors: tuple[DeviceError, ...] = ()


class DeviceInput(Protocol):
    """One device's adapter. Every method may raise :class:`gateway.errors.DeviceError`;
    no third-party exception leaves an adapter."""

    name: str

    async def connect(self) -> None:
        """Open the connection; raise DeviceError(kind='connect'|'auth'|...) on failure."""

    async def read(self) -> ReadResult:
        """Read every point once. Points whose block failed come back NaN with quality
        NO_COMM (or BAD); a failure of the whole device raises DeviceError."""

    async def close(self) -> None:
        """Close the connection; never raises."""
