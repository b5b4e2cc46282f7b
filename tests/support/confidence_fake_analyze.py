"""A stand-in for stiction.analyze for the list and the site calibration's gateway tests:
the confidence of stiction is the OP's peak-to-peak over the window / 40 (at most 0.999), the
verdict the shipped decision's thresholds of it (stiction at 0.87 and above, sized; no
stiction at 0.5 and under; undetermined between). Deterministic, fast, a thread's work."""

from __future__ import annotations

from typing import Any

import numpy as np

from stiction import Assessment, Verdict


def analyze(op: Any, pv: Any, *, ts: float, kp: float | None = None, delay: float = 0.0,
            process: str = "self-regulating", op_range: tuple[float, float] = (0.0, 100.0),
            k: float = 1.99) -> Assessment:
    conf = min(0.999, float(np.ptp(op)) / 40.0)
    if conf >= 0.87:
        return Assessment(Verdict.STICTION, f"fake: stiction, confidence {conf:.2f}",
                          oscillating=True, period_s=10.0 * ts, confidence=conf,
                          fd=0.02, fd_op=2.0)
    verdict = Verdict.NO_STICTION if conf <= 0.5 else Verdict.UNDETERMINED
    return Assessment(verdict, f"fake: {verdict}, confidence {conf:.2f}", oscillating=True,
                      period_s=10.0 * ts, confidence=conf)
