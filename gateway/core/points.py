"""Points and sample quality: raw values to engineering values, and what is plausible.

An input (a source) only decodes: per read it returns one *raw* value and one quality per point
(numpy arrays, in the point order it was built with). :class:`PointTable` is the one place
that turns them into engineering values (``raw * scale + offset``) and judges which are
**implausible**, for every protocol, for the poller and for ``probe`` alike
(:meth:`PointTable.judge`, the cause per point as :class:`Implausible`):

* NaN or ±inf (raw or after scaling);
* a subnormal number (magnitude below the smallest normal float32, 1.2e-38, but not 0): a
  float32 read with the wrong word order, nearly always (50.0 word-swapped is 2.4e-41);
* a magnitude above :data:`MAX_MAGNITUDE` (1e15, raw or after scaling), with or without a
  ``range``: random register garbage read as float32 is mostly huge (-2.9e38), no process
  value is;
* an engineering value outside the point's configured ``range``;
* an OP outside its loop's ``op_range`` by more than :data:`OP_MARGIN` of the span (OP is in
  % of valve span: -2.5e17 or 3,000 % is a wrong register, type or word order; a DCS may
  drive OP a few % beyond its span, -6.9 to 106.9 % on some).

An implausible sample is BAD in the windows (the analysis calls the loop ``bad_data``), and
NaN: never a zero. :func:`explain` says why in words with the likely cause (the address off
by one, the word order, with the value the other word order would give), the same words in
the poller's log line and in ``probe``'s ``IMPLAUSIBLE`` rows.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["FLOAT32_TINY", "MAX_MAGNITUDE", "OP_MARGIN", "Implausible", "PointSpec",
           "PointTable", "Quality", "explain"]

FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # smallest normal float32
MAX_MAGNITUDE = 1e15
"""No plausible sample is larger in magnitude (raw or engineering), ``range`` or not."""
OP_MARGIN = 0.1
"""How far, as a share of ``op_range``'s width, an OP may lie beyond it and still be
plausible (0..100 %: -10..110 %)."""


class Quality(enum.IntEnum):
    """Quality of one sample (stored as uint8 in windows and the state file)."""

    GOOD = 0
    UNCERTAIN = 1  # the source said uncertain (OPC UA) - kept as a gap by analysis
    BAD = 2  # the source said bad, or the value was NaN/inf/subnormal/out of range
    NO_COMM = 3  # the read failed (device down, timeout, exception for this block)
    MISSING = 4  # no poll happened for this slot (gateway was not running)


class Implausible(enum.IntEnum):
    """Why a sample the source read is not plausible (:meth:`PointTable.judge`); NONE for a
    plausible one, or one the source did not deliver GOOD."""

    NONE = 0
    NOT_FINITE = 1  # NaN or ±inf, raw or scaled
    SUBNORMAL = 2  # below the smallest normal float32 (not 0)
    HUGE = 3  # magnitude above MAX_MAGNITUDE, raw or scaled
    RANGE = 4  # outside the point's range
    OP_RANGE = 5  # an OP beyond its loop's op_range (by more than OP_MARGIN of it)


@dataclasses.dataclass(frozen=True)
class PointSpec:
    """One value to read. ``address`` is protocol-specific (a Modbus register spec or an
    OPC UA node id); ``scale``/``offset`` map raw to engineering units (raw*scale+offset);
    outside ``range`` (engineering units) a sample is BAD; an OP point's ``span`` is its
    loop's ``op_range`` (beyond it by more than :data:`OP_MARGIN`, BAD). ``origin`` says
    where the loop is listed, for messages (``loops.csv: line 4``; '' for the YAML)."""

    loop: str
    role: str  # "op" or "pv"
    address: Any
    scale: float = 1.0
    offset: float = 0.0
    range: tuple[float, float] | None = None
    span: tuple[float, float] | None = None
    origin: str = ""

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
        self.span_lo = np.full(n, -np.inf)
        self.span_hi = np.full(n, np.inf)
        for i, p in enumerate(self.points):
            if p.range is not None:
                self.lo[i], self.hi[i] = p.range
            if p.span is not None:
                self.span_lo[i], self.span_hi[i] = _widened(p.span)

    def __len__(self) -> int:
        return len(self.points)

    def engineering(self, raw: NDArray[np.float64], quality: NDArray[np.uint8]
                    ) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
        """Engineering values and qualities (new arrays): implausible GOOD samples become
        BAD, and every sample that is not GOOD is NaN."""
        values, quality, _causes = self.judge(raw, quality)
        return values, quality

    def judge(self, raw: NDArray[np.float64], quality: NDArray[np.uint8]
              ) -> tuple[NDArray[np.float64], NDArray[np.uint8], NDArray[np.uint8]]:
        """:meth:`engineering`, and per point why it was implausible (an
        :class:`Implausible` code; NONE where the source delivered no GOOD sample)."""
        raw = np.asarray(raw, dtype=np.float64)
        quality = np.array(quality, dtype=np.uint8)
        with np.errstate(invalid="ignore", over="ignore"):
            values = raw * self.scale + self.offset
            checks = [
                (~np.isfinite(raw) | ~np.isfinite(values), Implausible.NOT_FINITE),
                (_subnormal(raw) | _subnormal(values), Implausible.SUBNORMAL),
                ((np.abs(raw) > MAX_MAGNITUDE) | (np.abs(values) > MAX_MAGNITUDE),
                 Implausible.HUGE),
                ((values < self.lo) | (values > self.hi), Implausible.RANGE),
                ((values < self.span_lo) | (values > self.span_hi), Implausible.OP_RANGE),
            ]
        causes = np.select([c for c, _ in checks], [int(k) for _, k in checks],
                           Implausible.NONE).astype(np.uint8)
        causes[quality != Quality.GOOD] = Implausible.NONE
        quality[causes != Implausible.NONE] = Quality.BAD
        values[quality != Quality.GOOD] = np.nan
        return values, quality, causes

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


def explain(point: PointSpec, raw: float, cause: int) -> str:
    """Why ``raw`` (as the source decoded it) of ``point`` is implausible, and its likely
    cause: ``-2.5e+17 is beyond 1e15: register garbage; the address is likely off by one
    (...)``. With the other word order a plausible value is named."""
    eng = raw * point.scale + point.offset
    typ = str(getattr(point.address, "type", ""))  # Modbus points say their type
    garbage = ("; the address is likely off by one (a 32-bit value read from its second "
               "register, or a 1-based register list), or the type or word order is wrong"
               if typ in ("float32", "float64", "int32", "uint32", "") else
               "; the address, type or scale is likely wrong")
    if cause == Implausible.NOT_FINITE:
        text = f"{_g(raw)} is not a number" + garbage
    elif cause == Implausible.SUBNORMAL:
        text = (f"{_g(raw)} is a float too small for any measurement (subnormal): the word "
                f"order is likely wrong, or the address off by one")
    elif cause == Implausible.HUGE:
        text = f"{_g(raw)} is beyond {MAX_MAGNITUDE:g}: register garbage" + garbage
    elif cause == Implausible.RANGE:
        lo, hi = point.range or (-math.inf, math.inf)
        text = (f"{_g(eng)} is outside its range {lo:g}..{hi:g}: the address, type, word "
                f"order or scale is likely wrong, or the range")
    elif cause == Implausible.OP_RANGE:
        lo, hi = point.span or (-math.inf, math.inf)
        text = (f"{_g(eng)} is outside op_range {lo:g}..{hi:g} (OP is % of valve span, "
                f"{OP_MARGIN:.0%} of it allowed beyond): the address (off by one?), type, "
                f"word order or op scale is likely wrong")
    else:
        return ""
    other = _other_word_order(point, raw, typ)
    return text + (f"; with the other word order it reads {_g(other)}" if other is not None
                   else "")


def _other_word_order(point: PointSpec, raw: float, typ: str) -> float | None:
    """The engineering value of ``raw``'s float32 with its two registers swapped, if that is
    plausible (a word order to try), else None."""
    if typ != "float32" or not math.isfinite(raw):
        return None
    bits = int(np.array([raw], dtype=np.float32).view(np.uint32)[0])
    swapped = np.array([((bits >> 16) | (bits << 16)) & 0xFFFFFFFF], dtype=np.uint32)
    other = float(swapped.view(np.float32)[0])
    _v, _q, causes = PointTable([point]).judge(np.array([other]), np.zeros(1, np.uint8))
    return other * point.scale + point.offset if causes[0] == Implausible.NONE else None


def _g(x: float) -> str:
    return f"{x:.7g}" if math.isfinite(x) else str(x)


def _widened(span: tuple[float, float]) -> tuple[float, float]:
    lo, hi = span
    margin = OP_MARGIN * abs(hi - lo)
    return lo - margin, hi + margin


def _subnormal(x: NDArray[np.float64]) -> NDArray[np.bool_]:
    mag = np.abs(x)
    return (mag < FLOAT32_TINY) & (mag > 0)
