"""The one in-memory result store: the latest :class:`stiction.Assessment` per loop.

Every output (Modbus result registers, Prometheus metrics, the state file) is a view of this
store; nothing computes a result twice. Per loop it also keeps the latest OP/PV sample and
whether the loop is stale (no fresh samples), as numpy arrays indexed by the loop's position
in the config.

Subscribers (``store.subscribe(fn)``) are called with the loop index after each change of a
loop's assessment or stale flag, on the event loop thread. Readers on other threads (the
metrics HTTP server) take a :meth:`ResultStore.snapshot`, an immutable copy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment

from .plantview import ROLE_CODES, PlantView

__all__ = ["NO_POSITION", "LoopResult", "ResultStore", "StoreSnapshot", "verdict_name"]

NO_POSITION = 255
"""``position_quality`` of a loop without a position point (else a ``Quality`` code)."""


@dataclasses.dataclass(frozen=True, slots=True)
class LoopResult:
    """One loop's latest assessment with its bookkeeping."""

    assessment: Assessment
    seq: int  # 1, 2, ... per loop, never backwards across reloads and restarts (the
    # register wraps at 65536)
    t: float  # wall-clock Unix seconds of the assessment
    window_fill: float  # fraction 0-1 of the window holding good samples
    samples: int  # samples the analysis used
    judged: float | None = None  # wall Unix seconds of the round that judged the verdict
    # (None: this one, ``t``); older while it is held (core/hysteresis.py)
    hold: int = 0  # 0 judged this round, 1 held back (hysteresis), 2 held through warming up
    # the PV's swing over the window analysed (half its 2-98 % range, PV units;
    # stiction.ranking.swing): what the cycle costs, for the list worst first
    pv_swing: float | None = None
    since: float | None = None  # wall Unix seconds since which the loop has had this verdict

    @property
    def judged_at(self) -> float:
        """When the verdict shown was judged: ``t`` unless it is held."""
        return self.t if self.judged is None else self.judged


class ResultStore:
    """Latest result, latest sample and stale flag of every configured loop."""

    def __init__(self, loops: Sequence[str]) -> None:
        self.loops = tuple(loops)
        self.index = {name: i for i, name in enumerate(self.loops)}
        n = len(self.loops)
        self.results: list[LoopResult | None] = [None] * n
        self.latest_op: NDArray[np.float64] = np.full(n, np.nan)
        self.latest_pv: NDArray[np.float64] = np.full(n, np.nan)
        # the valve's latest position and its sample's quality (core.points.Quality; a loop
        # without a position point: NO_POSITION)
        self.latest_position: NDArray[np.float64] = np.full(n, np.nan)
        self.position_quality = np.full(n, NO_POSITION, dtype=np.uint8)
        self.stale = np.zeros(n, dtype=bool)
        # the loop's device is down: a stale loop of a down device is ``device_down``
        self.down = np.zeros(n, dtype=bool)
        # per loop, a sequence number already published (by an earlier run or config): the
        # next assessment is numbered above it, so the number never goes backwards
        self.seq_floor = np.zeros(n, dtype=np.int64)
        self.plant = PlantView()  # the plant-wide groups and roles (core/plantview.py)
        # the list worst first (core/ranking.py): each loop's place from 1 (0: not yet
        # ranked) and suspicion; the plant's weights of it: priority and the PV's span
        self.rank = np.zeros(n, dtype=np.int64)
        self.suspicion = np.full(n, np.nan)
        self.priority = np.ones(n)
        self.pv_span = np.full(n, np.nan)
        self._subscribers: list[Callable[[int], None]] = []

    def subscribe(self, fn: Callable[[int], None]) -> None:
        self._subscribers.append(fn)

    def _notify(self, i: int) -> None:
        for fn in self._subscribers:
            fn(i)

    def set_result(self, i: int, assessment: Assessment, *, t: float, window_fill: float,
                   samples: int, judged: float | None = None, hold: int = 0,
                   pv_swing: float | None = None) -> LoopResult:
        prev = self.results[i]
        seq = max(prev.seq if prev else 0, int(self.seq_floor[i])) + 1
        judged = None if judged is None or judged == t else judged
        since = prev.since if prev is not None and prev.since is not None \
            and prev.assessment.verdict == assessment.verdict else judged or t
        res = LoopResult(assessment, seq, t, window_fill, samples, judged, hold, pv_swing,
                         since)
        self.results[i] = res
        self._notify(i)
        return res

    def restore_result(self, i: int, result: LoopResult) -> None:
        """Put back a result as it was (sequence number included), e.g. from the state file
        or the previous config on reload."""
        self.results[i] = result
        self.seq_floor[i] = max(int(self.seq_floor[i]), result.seq)
        self._notify(i)

    def clear_result(self, i: int) -> None:
        """Forget loop ``i``'s result (a restore that failed half-way starts empty)."""
        self.results[i] = None
        self._notify(i)

    def last_seq(self, i: int) -> int:
        """The highest sequence number loop ``i`` has published (0: none)."""
        res = self.results[i]
        return max(res.seq if res is not None else 0, int(self.seq_floor[i]))

    def set_stale(self, rows: NDArray[np.intp], stale: NDArray[np.bool_] | bool,
                  down: bool = False) -> None:
        """Set the stale flag of loops ``rows`` and whether their device is ``down``;
        subscribers hear of those whose verdict name changed."""
        new = np.broadcast_to(np.asarray(stale, dtype=bool), rows.shape)
        changed = rows[(self.stale[rows] != new) | (new & (self.down[rows] != down))]
        self.stale[rows] = new
        self.down[rows] = down
        for i in changed:
            self._notify(int(i))

    def verdict_name(self, i: int) -> str:
        return verdict_name(self.results[i], bool(self.stale[i]), bool(self.down[i]))

    def set_plant(self, view: PlantView) -> None:
        """Replace the plant view; subscribers hear of the loops whose group, role or
        source changed."""
        old, self.plant = self.plant, view
        for name in set(old.roles) | set(view.roles):
            i = self.index.get(name)
            if i is not None and old.of(name) != view.of(name):
                self._notify(i)

    def set_ranks(self, rank: NDArray[np.int64], suspicion: NDArray[np.float64]) -> None:
        """The list's new places and scores (core/ranking.py); subscribers hear of the loops
        whose place or score changed."""
        changed = np.flatnonzero((self.rank != rank) | ~(
            (self.suspicion == suspicion) | (np.isnan(self.suspicion) & np.isnan(suspicion))))
        self.rank[:] = rank
        self.suspicion[:] = suspicion
        for i in changed:
            self._notify(int(i))

    def plant_registers(self, i: int) -> tuple[int, int, int]:
        """Loop ``i``'s (group number, role code, source loop's index from 1 in config
        order; 0: none) for its result block."""
        number, role, source = self.plant.of(self.loops[i])
        where = self.index.get(source) if source is not None else None
        return number, ROLE_CODES[role], 0 if where is None else where + 1

    def snapshot(self) -> StoreSnapshot:
        """An immutable copy of everything a reader needs (cheap: the results are shared,
        the arrays copied)."""
        return StoreSnapshot(self.loops, tuple(self.results), self.latest_op.copy(),
                             self.latest_pv.copy(), self.stale.copy(), self.down.copy(),
                             self.plant, self.latest_position.copy(),
                             self.position_quality.copy(), self.rank.copy(),
                             self.suspicion.copy())


@dataclasses.dataclass(frozen=True)
class StoreSnapshot:
    """The store at one moment, safe to read from another thread."""

    loops: tuple[str, ...]
    results: tuple[LoopResult | None, ...]
    latest_op: NDArray[np.float64]
    latest_pv: NDArray[np.float64]
    stale: NDArray[np.bool_]
    down: NDArray[np.bool_]
    plant: PlantView = dataclasses.field(default_factory=PlantView)
    latest_position: NDArray[np.float64] | None = None  # None: as NaN / NO_POSITION
    position_quality: NDArray[np.uint8] | None = None
    rank: NDArray[np.int64] | None = None  # None: not ranked (0)
    suspicion: NDArray[np.float64] | None = None

    def verdict_name(self, i: int) -> str:
        return verdict_name(self.results[i], bool(self.stale[i]), bool(self.down[i]))


def verdict_name(result: LoopResult | None, stale: bool = False, down: bool = False) -> str:
    """``device_down`` (stale because its device is down: the device's alert says why, not
    one per loop), ``stale``, ``none`` (no assessment yet) or the assessment's verdict."""
    if stale:
        return "device_down" if down else "stale"
    return "none" if result is None else str(result.assessment.verdict)
