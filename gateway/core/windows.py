"""Per-loop sliding windows as fixed-size numpy ring buffers.

A :class:`WindowBank` holds every loop that is sampled together (one device) and has the
same window length, as time-major 2-D arrays: ``op`` and ``pv`` float32 of shape
(size, loops), ``quality`` uint8 of the same shape and one float64 timestamp per slot. An
append writes one row (a few vectorised copies, whatever the number of loops); no Python
object is kept per sample, so a sample costs 9 bytes per loop plus 8 bytes per row.

Timestamps are process time: Unix seconds when ``time_scale`` is 1, otherwise the gateway's
start time plus the elapsed wall time multiplied by ``time_scale``.

:func:`analysis_segment` turns a raw window into what the analysis gets: the trailing run of
usable samples, short gaps filled by linear interpolation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..inputs.base import Quality

__all__ = ["WindowBank", "analysis_segment"]

F32 = NDArray[np.float32]


class WindowBank:
    """Ring buffers of ``len(loops)`` loops sampled together, ``size`` samples each."""

    def __init__(self, loops: Sequence[str], size: int) -> None:
        if size < 2:
            raise ValueError(f"size must be at least 2, was {size}")
        self.loops = tuple(loops)
        self.size = int(size)
        n = len(self.loops)
        self.op: F32 = np.full((self.size, n), np.nan, dtype=np.float32)
        self.pv: F32 = np.full((self.size, n), np.nan, dtype=np.float32)
        self.quality = np.full((self.size, n), Quality.MISSING, dtype=np.uint8)
        self.t = np.full(self.size, np.nan, dtype=np.float64)
        self.head = 0  # next slot written
        self.count = 0  # slots written so far (at most size)

    @property
    def nbytes(self) -> int:
        return self.op.nbytes + self.pv.nbytes + self.quality.nbytes + self.t.nbytes

    def append(self, t: float, op: NDArray[np.floating], pv: NDArray[np.floating],
               quality: NDArray[np.uint8]) -> None:
        """Store one sample of every loop (arrays of len(loops), in loop order)."""
        i = self.head
        self.op[i] = op
        self.pv[i] = pv
        self.quality[i] = quality
        self.t[i] = t
        self.head = (i + 1) % self.size
        self.count = min(self.count + 1, self.size)

    def _order(self) -> NDArray[np.intp]:
        """Slot indices of the stored samples, oldest first."""
        if self.count < self.size:
            return np.arange(self.count)
        return (np.arange(self.size) + self.head) % self.size

    def series(self, columns: Sequence[int] | NDArray[np.intp]
               ) -> tuple[NDArray[np.float64], F32, F32, NDArray[np.uint8]]:
        """Chronological copies for the given loop columns: t (m,), op/pv/quality (k, m)."""
        order = self._order()
        cols = np.asarray(columns, dtype=np.intp)
        rows = np.ix_(order, cols)
        return (self.t[order], self.op[rows].T.copy(), self.pv[rows].T.copy(),
                self.quality[rows].T.copy())

    def latest(self) -> tuple[F32, F32, NDArray[np.uint8]]:
        """The newest sample of every loop (NaN / MISSING before the first append)."""
        i = (self.head - 1) % self.size
        return self.op[i].copy(), self.pv[i].copy(), self.quality[i].copy()


def analysis_segment(op: NDArray[np.floating], pv: NDArray[np.floating],
                     quality: NDArray[np.uint8], max_fill: int = 3
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The trailing stretch of a window the analysis should see, as float64.

    Gaps (quality not GOOD) of at most ``max_fill`` samples are filled by linear
    interpolation between their neighbours; the segment starts after the last longer gap
    (and after leading samples that were never written). May be empty."""
    good = quality == Quality.GOOD
    n = len(good)
    if not good.any():
        return np.empty(0), np.empty(0)
    bad = ~good
    # run lengths of bad stretches, to find the last one longer than max_fill
    start = 0
    edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.view(np.int8), [0]))))
    runs = edges.reshape(-1, 2)  # [begin, end) of each bad run
    for b, e in runs[::-1]:
        if e - b > max_fill or b == 0 or e == n:
            if e == n:  # trailing gap: a stale loop; keep the samples before it
                continue
            start = int(e)
            break
    last_good = int(np.flatnonzero(good)[-1])
    seg = slice(start, last_good + 1)
    g = good[seg]
    o = np.asarray(op[seg], dtype=np.float64)
    p = np.asarray(pv[seg], dtype=np.float64)
    if not g.all():
        x = np.arange(len(g))
        o = np.interp(x, x[g], o[g])
        p = np.interp(x, x[g], p[g])
    return o, p
