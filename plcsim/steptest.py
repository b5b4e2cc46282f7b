"""The simulated PLC's step-test mode: one loop held in manual while OP plays a step test.

From ``start_s`` (process seconds) the loop's controller is in manual and its OP steps
through :func:`stiction.valvetest.step_test_levels` around the OP it had then (moved inside
25 .. 75 % so the whole sequence fits the span), each level held ``hold_s``; afterwards
the PLC holds the last level, in manual, as an engineer's test leaves a loop. With
``record`` it writes what it served while the test ran (``t, op, pv, position``: process
seconds, OP and position in % of span, PV in process units) as a historian export that
``stiction valve-test FILE --op-range 0 100`` reads (add ``--position position`` for the
valve's own travel).
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

from stiction.valvetest import step_test_levels

__all__ = ["StepTest", "StepTestPlayer"]

log = logging.getLogger("gateway.plc_sim")
REACH = 25.0  # % of span each staircase travels (the sequence's default)


@dataclasses.dataclass(frozen=True)
class StepTest:
    """The ``step_test`` section of the simulated PLC's config."""

    loop: str
    start_s: float = 0.0
    hold_s: float = 60.0
    record: Path | None = None


class StepTestPlayer:
    """Plays one :class:`StepTest`: :meth:`manual` is the OP (fraction of span) the loop is
    held at, at process time ``t`` (None while it is still in automatic)."""

    def __init__(self, test: StepTest) -> None:
        self.test = test
        self.levels: np.ndarray | None = None  # % of span, fixed when the test begins
        self.done = False
        self._file: TextIO | None = None
        self._writer: csv.DictWriter[str] | None = None

    def manual(self, t: float, op_now: float) -> float | None:
        if t < self.test.start_s:
            return None
        if self.levels is None:
            op0 = min(max(round(op_now, 1), REACH), 100.0 - REACH)
            self.levels = step_test_levels(op0, reach=REACH)
            log.info("plc-sim: step test of %s begins: %d steps of %g s from OP %.1f %%",
                     self.test.loop, self.levels.size - 1, self.test.hold_s, op0)
            self._open()
        i = math.floor((t - self.test.start_s) / self.test.hold_s + 1e-9)
        if i >= self.levels.size and not self.done:
            self.done = True
            log.info("plc-sim: step test of %s done; the loop stays in manual at %.1f %%",
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
