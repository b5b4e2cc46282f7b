"""The one in-memory result store: the latest :class:`stiction.Assessment` per loop.

Every output (Modbus result registers, Prometheus metrics, later the state file) is a view
of this store; nothing computes a result twice. Per loop it also keeps the latest OP/PV
sample and whether the loop is stale (no fresh samples), as numpy arrays indexed by the
loop's position in the config.

Subscribers (``store.subscribe(fn)``) are called with the loop index after each change of a
loop's assessment or stale flag, on the event loop thread.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment, Verdict

__all__ = ["VERDICT_CODES", "LoopResult", "ResultStore", "verdict_code"]

VERDICT_CODES: dict[str, int] = {
    "none": 0,
    Verdict.NOT_OSCILLATING: 1,
    Verdict.NO_STICTION: 2,
    Verdict.UNDETERMINED: 3,
    Verdict.STICTION: 4,
    Verdict.BAD_DATA: 5,
    "stale": 6,
}
"""Verdict codes of the result registers (docs/modbus-map.md)."""


@dataclasses.dataclass(frozen=True, slots=True)
class LoopResult:
    """One loop's latest assessment with its bookkeeping."""

    assessment: Assessment
    seq: int  # 1, 2, ... per loop (the register wraps at 65536)
    t: float  # wall-clock Unix seconds of the assessment
    window_fill: float  # fraction 0-1 of the window holding good samples
    samples: int  # samples the analysis used


class ResultStore:
    """Latest result, latest sample and stale flag of every configured loop."""

    def __init__(self, loops: Sequence[str]) -> None:
        self.loops = tuple(loops)
        self.index = {name: i for i, name in enumerate(self.loops)}
        n = len(self.loops)
        self.results: list[LoopResult | None] = [None] * n
        self.latest_op: NDArray[np.float64] = np.full(n, np.nan)
        self.latest_pv: NDArray[np.float64] = np.full(n, np.nan)
        self.stale = np.zeros(n, dtype=bool)
        self._subscribers: list[Callable[[int], None]] = []

    def subscribe(self, fn: Callable[[int], None]) -> None:
        self._subscribers.append(fn)

    def _notify(self, i: int) -> None:
        for fn in self._subscribers:
            fn(i)

    def set_result(self, i: int, assessment: Assessment, *, t: float, window_fill: float,
                   samples: int) -> LoopResult:
        prev = self.results[i]
        res = LoopResult(assessment, (prev.seq + 1) if prev else 1, t, window_fill, samples)
        self.results[i] = res
        self._notify(i)
        return res

    def restore_result(self, i: int, result: LoopResult) -> None:
        """Put back a result as it was (sequence number included), e.g. from the state file
        or the previous config on reload."""
        self.results[i] = result
        self._notify(i)

    def set_stale(self, rows: NDArray[np.intp], stale: NDArray[np.bool_] | bool) -> None:
        """Set the stale flag of loops ``rows``; subscribers hear of those that changed."""
        new = np.broadcast_to(np.asarray(stale, dtype=bool), rows.shape)
        changed = rows[self.stale[rows] != new]
        self.stale[rows] = new
        for i in changed:
            self._notify(int(i))

    def verdict_code(self, i: int) -> int:
        return verdict_code(self.results[i], bool(self.stale[i]))

    def verdict_name(self, i: int) -> str:
        if self.stale[i]:
            return "stale"
        res = self.results[i]
        return "none" if res is None else str(res.assessment.verdict)


def verdict_code(result: LoopResult | None, stale: bool = False) -> int:
    if stale:
        return VERDICT_CODES["stale"]
    if result is None:
        return VERDICT_CODES["none"]
    return VERDICT_CODES[result.assessment.verdict]
