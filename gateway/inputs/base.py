"""The interface every input implements: a :class:`Source`.

A source serves one device (one PLC, one connection). It is built with the device's config
and the ordered list of points (each loop contributes its OP point and its PV point) and
returns, per read, one *raw* value and one quality per point, as numpy arrays in the same
order: no per-sample Python objects, so 10,000 loops cost a few array operations.

A source only decodes. Scaling to engineering units and plausibility checks happen once, for
every protocol, in :class:`gateway.core.points.PointTable`; reconnecting (backoff, logging an
outage once) is the poller's job (:mod:`gateway.runtime.poller`). A point that could not be
read is NaN with a non-GOOD quality: never a zero.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ..core.points import PointSpec, Quality
from ..errors import DeviceError

__all__ = ["PointSpec", "PointStatus", "Quality", "ReadResult", "Source"]


@dataclasses.dataclass(frozen=True)
class ReadResult:
    """One read of one device: raw ``values`` float64 and ``quality`` uint8, one per point,
    and the wall-clock time (Unix seconds) the read started. ``requests`` counts protocol
    requests the read sent. ``errors`` lists partial failures (e.g. a Modbus exception for
    one block) whose points came back NaN/NO_COMM while the rest of the read succeeded."""

    t: float
    values: NDArray[np.float64]
    quality: NDArray[np.uint8]
    requests: int
    errors: tuple[DeviceError, ...] = ()


class Source(Protocol):
    """One device's input. Every method may raise :class:`gateway.errors.DeviceError`;
    no third-party exception leaves a source."""

    name: str

    async def connect(self) -> None:
        """Open the connection; raise DeviceError(kind='connect'|'auth'|...) on failure.
        One attempt: the caller decides when to try again."""

    async def read(self) -> ReadResult:
        """Read every point once. Points whose block failed come back NaN with quality
        NO_COMM (or BAD); a failure of the whole device raises DeviceError."""

    async def close(self) -> None:
        """Close the connection; never raises."""


@runtime_checkable
class PointStatus(Protocol):
    """A source that can say, per point, what the device said of it at its last read
    (``stiction-gateway probe`` prints it); optional."""

    def point_status(self) -> list[str]:
        """One text per point, in point order: '' when there is nothing to say, else the
        protocol's words for the failure (e.g. ``holding 100+4: illegal data address
        (exception 2): ...``, ``BadNodeIdUnknown``)."""
