"""Per-loop sliding windows as fixed-size numpy ring buffers.

A :class:`WindowBank` holds every loop that is sampled together (one device) and has the
same window length, as time-major 2-D arrays: ``op`` and ``pv`` float32 of shape
(size, loops), ``quality`` uint8 of the same shape and one float64 timestamp per slot. An
append writes one row (a few vectorised copies, whatever the number of loops); no Python
object is kept per sample, so a sample costs 9 bytes per loop plus 8 bytes per row. A bank
one of whose loops reads the valve's position holds a third signal, ``position`` (float32,
NaN where the loop has none or its sample was not GOOD: the position's quality never makes
the OP/PV window bad, the analysis then measures without it), 4 bytes more per loop.

Timestamps are process time: Unix seconds when ``time_scale`` is 1, otherwise the gateway's
start time plus the elapsed wall time multiplied by ``time_scale``.

:func:`analysis_segment` turns a raw window into what the analysis gets: the trailing run of
usable samples, short gaps filled by linear interpolation.

A :class:`LoopGroup` is what the rest of the gateway passes around: one bank and, per column,
the loop's config, the positions of its OP and PV in its device's point list and its row in
the result store. :func:`record` appends one poll of a device to its groups.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..config.model import Config, LoopConfig
from .points import Quality
from .store import NO_POSITION, ResultStore

__all__ = ["LoopGroup", "WindowBank", "analysis_segment", "load_columns", "loop_signature",
           "position_segment", "record", "result_signature", "segment_of"]

F32 = NDArray[np.float32]


class WindowBank:
    """Ring buffers of ``len(loops)`` loops sampled together, ``size`` samples each."""

    def __init__(self, loops: Sequence[str], size: int, *, position: bool = False) -> None:
        if size < 2:
            raise ValueError(f"size must be at least 2, was {size}")
        self.loops = tuple(loops)
        self.size = int(size)
        n = len(self.loops)
        self.op: F32 = np.full((self.size, n), np.nan, dtype=np.float32)
        self.pv: F32 = np.full((self.size, n), np.nan, dtype=np.float32)
        self.position: F32 | None = (np.full((self.size, n), np.nan, dtype=np.float32)
                                     if position else None)
        self.quality = np.full((self.size, n), Quality.MISSING, dtype=np.uint8)
        self.t = np.full(self.size, np.nan, dtype=np.float64)
        self.head = 0  # next slot written
        self.count = 0  # slots written so far (at most size)

    @property
    def nbytes(self) -> int:
        pos = 0 if self.position is None else self.position.nbytes
        return self.op.nbytes + self.pv.nbytes + self.quality.nbytes + self.t.nbytes + pos

    def append(self, t: float, op: NDArray[np.floating], pv: NDArray[np.floating],
               quality: NDArray[np.uint8], position: NDArray[np.floating] | None = None
               ) -> None:
        """Store one sample of every loop (arrays of len(loops), in loop order); ``position``
        (NaN: none) where the bank holds one (else ignored; None: NaN)."""
        i = self.head
        self.op[i] = op
        self.pv[i] = pv
        if self.position is not None:
            self.position[i] = np.nan if position is None else position
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

    def positions(self, columns: Sequence[int] | NDArray[np.intp]) -> F32 | None:
        """Chronological copies of the given loop columns' positions (k, m), as
        :meth:`series`; None when the bank holds none."""
        if self.position is None:
            return None
        rows = np.ix_(self._order(), np.asarray(columns, dtype=np.intp))
        return self.position[rows].T.copy()

    def rows(self) -> tuple[NDArray[np.float64], F32, F32, NDArray[np.uint8], F32 | None]:
        """Chronological copies of every loop as stored, time-major: t (m,), op/pv/quality
        and position (None: the bank holds none) (m, loops). One copy of the bank, already
        in the state file's layout (:meth:`series` copies twice, once transposed)."""
        order = self._order()
        return (self.t[order], self.op[order], self.pv[order], self.quality[order],
                None if self.position is None else self.position[order])

    def latest(self) -> tuple[F32, F32, NDArray[np.uint8]]:
        """The newest sample of every loop (NaN / MISSING before the first append)."""
        i = (self.head - 1) % self.size
        return self.op[i].copy(), self.pv[i].copy(), self.quality[i].copy()


def load_columns(bank: WindowBank, t: NDArray[np.float64],
                 columns: Mapping[int, tuple[Any, ...]]) -> None:
    """Fill a fresh ``bank`` with chronological samples: ``t`` (rows) and per column index
    its op/pv/quality series and, optionally, its position series (kept where the bank
    holds positions); series are aligned at their newest sample (shorter ones get MISSING
    rows in front), at most ``bank.size`` newest rows are kept. Columns not given stay
    empty (MISSING)."""
    rows = min(len(t), bank.size)
    if rows == 0:
        return
    bank.t[:] = np.nan
    bank.t[:rows] = t[len(t) - rows:]
    for col, (op, pv, q, *pos) in columns.items():
        n = min(len(op), rows)
        if n == 0:
            continue
        bank.op[rows - n:rows, col] = op[len(op) - n:]
        bank.pv[rows - n:rows, col] = pv[len(pv) - n:]
        bank.quality[rows - n:rows, col] = q[len(q) - n:]
        if pos and pos[0] is not None and bank.position is not None:
            bank.position[rows - n:rows, col] = pos[0][len(pos[0]) - n:]
    bank.count = rows
    bank.head = rows % bank.size


@dataclasses.dataclass(frozen=True, eq=False)
class LoopGroup:
    """Loops of one device with the same window length, sampled together: one window
    bank and, per column, the loop's config, the positions of its OP and PV (and of the
    valve's position, -1 where the loop has none) in the device's point list and its row in
    the result store. ``ts``: the sample time."""

    device: str
    bank: WindowBank
    configs: tuple[LoopConfig, ...]
    op_points: NDArray[np.intp]
    pv_points: NDArray[np.intp]
    rows: NDArray[np.intp]
    ts: float
    pos_points: NDArray[np.intp] | None = None  # None: no loop of the group has one

    @property
    def loops(self) -> tuple[str, ...]:
        return self.bank.loops


def loop_signature(config: Config, loop: LoopConfig, samples: int | None = None) -> str:
    """What a loop's window depends on: equal signatures mean the stored samples are the
    same quantity at the same sample time, so the window can be kept. ``samples``: the
    window length to sign with instead of the config's (a window of another length holds
    the same samples: compared with the length it was saved or kept with, a window whose
    ``window_s`` alone changed keeps its newest samples)."""
    dev = config.device(loop.device)
    position = () if loop.position is None else (loop.position,)
    return repr((dev.protocol, dev.options, dev.poll_interval_s,
                 config.window_samples(loop) if samples is None else samples,
                 loop.op, loop.pv, *position))


def result_signature(config: Config, loop: LoopConfig) -> str:
    """What a loop's assessment depends on (its block address does not count)."""
    return repr((loop_signature(config, loop),
                 dataclasses.replace(loop, result_address=0)))


def record(groups: Sequence[LoopGroup], t: float, values: NDArray[np.float64],
           quality: NDArray[np.uint8], store: ResultStore) -> NDArray[np.bool_]:
    """Append one poll of a device (engineering values and qualities, one per point) to
    its groups, and set the store's latest OP/PV (and position with its quality). Returns,
    for the groups' loops in order, whether the sample was fresh (delivered by the device,
    good or not)."""
    fresh = []
    for g in groups:
        op, pv = values[g.op_points], values[g.pv_points]
        q = np.maximum(quality[g.op_points], quality[g.pv_points])
        position = None
        if g.pos_points is not None:
            has = g.pos_points >= 0
            at = np.where(has, g.pos_points, 0)
            pq = np.where(has, quality[at], NO_POSITION).astype(np.uint8)
            position = np.where(pq == Quality.GOOD, values[at], np.nan)
            store.latest_position[g.rows] = np.where(has, values[at], np.nan)
            store.position_quality[g.rows] = pq
        g.bank.append(t, op, pv, q, position)
        store.latest_op[g.rows] = op
        store.latest_pv[g.rows] = pv
        fresh.append(q < Quality.NO_COMM)
    return np.concatenate(fresh) if fresh else np.zeros(0, dtype=bool)


def analysis_segment(op: NDArray[np.floating], pv: NDArray[np.floating],
                     quality: NDArray[np.uint8], max_fill: int = 3
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The trailing stretch of a window the analysis should see, as float64.

    Gaps (quality not GOOD) of at most ``max_fill`` samples are filled by linear
    interpolation between their neighbours; the segment starts after the last longer gap
    (and after leading samples that were never written). May be empty."""
    o, p, _start = segment_of(op, pv, quality, max_fill)
    return o, p


def position_segment(position: NDArray[np.floating], start: int, length: int
                     ) -> NDArray[np.float64]:
    """The valve's position over the analysis segment (``start``, ``length`` from
    :func:`segment_of`), as float64: NaN where it was not GOOD (the travel measurement fills
    short gaps itself and leaves a gappy position to OP and PV)."""
    return np.asarray(position[start:start + length], dtype=np.float64)


def segment_of(op: NDArray[np.floating], pv: NDArray[np.floating],
               quality: NDArray[np.uint8], max_fill: int = 3
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """:func:`analysis_segment` and the index of its first sample in the window."""
    good = quality == Quality.GOOD
    n = len(good)
    if not good.any():
        return np.empty(0), np.empty(0), 0
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
    return o, p, start
