"""A stand-in for stiction.analyze, used only by gateway pipeline tests that check plumbing
(the real analysis is tested in the end-to-end test). Deterministic: the verdict depends on
the peak-to-peak OP of the window's last 300 samples."""

from __future__ import annotations

from typing import Any

import numpy as np

from stiction import Assessment, Verdict


def analyze(op: Any, pv: Any, *, ts: float, kp: float | None = None, delay: float = 0.0,
            process: str = "self-regulating", op_range: tuple[float, float] = (0.0, 100.0),
            k: float = 1.99) -> Assessment:
    amp = float(np.ptp(op[-300:]))
    if amp > 10.0:
        return Assessment(Verdict.STICTION, f"fake: OP swings {amp:.1f} %", oscillating=True,
                          period_s=100.0 * ts, stiction_index=0.8, fd=amp / 400.0,
                          fs=None if kp is None else amp / 300.0, jump=amp / 1200.0)
    return Assessment(Verdict.NOT_OSCILLATING, f"fake: OP swings {amp:.1f} %")
