"""Points and sample quality: raw values to engineering values, and what is plausible.

An input (a source) only decodes: per read it returns one *raw* value and one quality per point
(numpy arrays, in the point order it was built with). :class:`PointTable` is the one place
that turns them into engineering values (``raw * scale + offset``) and flags implausible
ones BAD, for every protocol:

* NaN or ±inf (raw or after scaling);
* a subnormal number (magnitude below the smallest normal float32, 1.2e-38, but not 0): a
  float32 read with the wrong word order, nearly always (50.0 word-swapped is 2.4e-41);
* a magnitude above :data:`MAX_MAGNITUDE` (1e15, raw or after scaling), with or without a
  ``range``: random register garbage read as float32 is mostly huge (-2.9e38), no process
  value is;
* an engineering value outside the point's configured ``range``.

A sample that is not GOOD is NaN in the result: never a zero.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["FLOAT32_TINY", "MAX_MAGNITUDE", "PointSpec", "PointTable", "Quality"]

FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # smallest normal float32
MAX_MAGNITUDE = 1e15
"""No plausible sample is larger in magnitude (raw or engineering), ``range`` or not."""


class Quality(enum.IntEnum):
    """Quality of one sample (stored as uint8 in windows and the state file)."""

    GOOD = 0
    UNCERTAIN = 1  # the source said uncertain (OPC UA) - kept as a gap by analysis
    BAD = 2  # the source said bad, or the value was NaN/inf/subnormal/out of range
    NO_COMM = 3  # the read failed (device down, timeout, exception for this block)
    MISSING = 4  # no poll happened for this slot (gateway was not running)


@dataclasses.dataclass(frozen=True)
class PointSpec:
    """One value to read. ``address`` is protocol-specific (a Modbus register spec or an
    OPC UA node id); ``scale``/``offset`` map raw to engineering units (raw*scale+offset);
    outside ``range`` (engineering units) a sample is BAD."""

    loop: str
    role: str  # "op" or "pv"
    address: Any
    scale: float = 1.0
    offset: float = 0.0
    range: tuple[float, float] | None = None

    @property
    def name(self) -> str:
        return f"{self.loop}.{self.role}"


class PointTable:
    """Scale, offset and plausible range of a device's points, as arrays."""

    def __init__(self, points: Sequence[PointSpec]) -> None:
        self.points = tuple(points)
        n = len(self.points)
        self.scale = np.array([p.scale for p in self.points], dtype=np.float64)
        self.offset = np.array([p.offset for p in self.points], dtype=np.float64)
        self.lo = np.full(n, -np.inf)
        self.hi = np.full(n, np.inf)
        for i, p in enumerate(self.points):
            if p.range is not None:
                self.lo[i], self.hi[i] = p.range

    def __len__(self) -> int:
        return len(self.points)

    def engineering(self, raw: NDArray[np.float64], quality: NDArray[np.uint8]
                    ) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
        """Engineering values and qualities (new arrays): implausible GOOD samples become
        BAD, and every sample that is not GOOD is NaN."""
        raw = np.asarray(raw, dtype=np.float64)
        quality = np.array(quality, dtype=np.uint8)
        with np.errstate(invalid="ignore", over="ignore"):
            values = raw * self.scale + self.offset
            implausible = (~np.isfinite(raw) | ~np.isfinite(values)
                           | _subnormal(raw) | _subnormal(values)
                           | (np.abs(raw) > MAX_MAGNITUDE) | (np.abs(values) > MAX_MAGNITUDE)
                           | (values < self.lo) | (values > self.hi))
        quality[implausible & (quality == Quality.GOOD)] = Quality.BAD
        values[quality != Quality.GOOD] = np.nan
        return values, quality

    def gap(self) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
        """A poll that did not happen or failed: NaN, NO_COMM for every point."""
        return (np.full(len(self), np.nan),
                np.full(len(self), Quality.NO_COMM, dtype=np.uint8))

    def names(self, indices: Iterable[int], limit: int = 5) -> str:
        """``FIC101.op, FIC101.pv`` for log lines (at most ``limit``, then "and N more")."""
        idx = sorted(indices)
        names = [self.points[i].name if i < len(self.points) else f"point {i}" for i in idx]
        more = f" and {len(names) - limit} more" if len(names) > limit else ""
        return ", ".join(names[:limit]) + more


def _subnormal(x: NDArray[np.float64]) -> NDArray[np.bool_]:
    mag = np.abs(x)
    return (mag < FLOAT32_TINY) & (mag > 0)
