"""The simulated PLC's step-test mode: one loop held in manual while OP plays a step test
an operator would allow on a running plant.

From ``start_s`` (process seconds) the loop's controller is in manual at the OP it had
then (no bump: the operating point), and held there for :data:`SETTLE_HOLDS` holds while
PV settles from whatever automatic left it doing; then OP steps through
:func:`stiction.valvetest.operator_levels` around that point: 0.5, 1 and 2 % of span, two
steps up, four down, two up for each, 24 steps, never more than 4 % of span from the
operating point (moved inside 4 .. 96 % only where the span does not leave room), and
back to it at the end. Each level is held ``hold_s``; by default as long as the loop's
process needs to settle (:func:`default_hold_s`). Afterwards the PLC holds the loop in
manual at the operating point, as an engineer's test leaves a loop. With ``record`` it
writes what it served while the test ran (``t, op, pv, position``: process seconds, OP
and position in % of span, PV in process units) as a historian export that ``stiction
valve-test FILE --op-range 0 100`` reads (add ``--position position`` for the valve's
own travel).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import logging
import math
from pathlib import Path
from typing import TextIO

import numpy as np

from stiction.valvetest import operator_levels
from stiction.valvetest.sequence import OPERATOR_COUNT, OPERATOR_STEPS

__all__ = ["SETTLE_HOLDS", "StepTest", "StepTestPlayer", "default_hold_s"]

log = logging.getLogger("gateway.plc_sim")
REACH = OPERATOR_COUNT * max(OPERATOR_STEPS)  # % of span OP goes from the operating point
SETTLE_HOLDS = 2
"""Holds at the operating point, in manual, before the first step (PV settles)."""
MIN_HOLD_S = 30.0  # the shortest default hold, process s


def default_hold_s(tau: float, theta: float, integrating: bool, ts: float) -> float:
    """A hold long enough for the process to settle after a step: its dead time plus four
    time constants (an integrating process's rate settles after the dead time and a few
    samples), at least :data:`MIN_HOLD_S` and five samples, rounded up to 10 s."""
    need = theta + (5.0 * ts if integrating else 4.0 * tau)
    return float(10.0 * math.ceil(max(need, MIN_HOLD_S, 5.0 * ts) / 10.0))


@dataclasses.dataclass(frozen=True)
class StepTest:
    """The ``step_test`` section of the simulated PLC's config (``hold_s`` None: the
    loop's :func:`default_hold_s`)."""

    loop: str
    start_s: float = 0.0
    hold_s: float | None = None
    record: Path | None = None


class StepTestPlayer:
    """Plays one :class:`StepTest` with holds of ``hold_s``: :meth:`manual` is the OP
    (fraction of span) the loop is held at, at process time ``t`` (None while it is still
    in automatic)."""

    def __init__(self, test: StepTest, hold_s: float) -> None:
        self.test = test
        self.hold_s = hold_s
        self.levels: np.ndarray | None = None  # % of span per hold, fixed when it begins
        self.done = False
        self._file: TextIO | None = None
        self._writer: csv.DictWriter[str] | None = None

    def manual(self, t: float, op_now: float) -> float | None:
        """``op_now``: the loop's OP (% of span) as automatic left it."""
        if t < self.test.start_s:
            return None
        if self.levels is None:
            op0 = min(max(op_now, REACH), 100.0 - REACH)
            steps = operator_levels(op0)
            self.levels = np.r_[np.full(SETTLE_HOLDS, op0), steps[1:]]
            log.info("plc-sim: step test of %s begins in manual at OP %.2f %%: settles "
                     "%g s, then %d steps of %g s (0.5 to 2 %%, within %g %% of it)",
                     self.test.loop, op0, SETTLE_HOLDS * self.hold_s, steps.size - 1,
                     self.hold_s, REACH)
            self._open()
        i = math.floor((t - self.test.start_s) / self.hold_s + 1e-9)
        if i >= self.levels.size and not self.done:
            self.done = True
            log.info("plc-sim: step test of %s done; the loop stays in manual at %.2f %%",
                     self.test.loop, self.levels[-1])
            self.close()
        return float(self.levels[min(i, self.levels.size - 1)]) / 100.0

    def _open(self) -> None:
        if self.test.record is None:
            return
        self.test.record.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.test.record.open("w", encoding="utf-8", newline="")
        self._writer = csv.DictWriter(self._file, ("t", "op", "pv", "position"))
        self._writer.writeheader()

    def record(self, t: float, op: float, pv: float, position: float) -> None:
        """One served sample (while the test runs and a record file is open)."""
        if self._writer is not None and not self.done:
            self._writer.writerow({"t": f"{t:g}", "op": f"{op:.6g}", "pv": f"{pv:.6g}",
                                   "position": f"{position:.6g}"})

    def close(self) -> None:
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            log.info("plc-sim: step test of %s recorded in %s", self.test.loop,
                     self.test.record)
        self._file = self._writer = None
