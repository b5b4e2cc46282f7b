"""Stand-in for stiction.analyze (not in the tree yet) for the OPC UA end-to-end plumbing
test: STICTION when the window's OP swings more than 10 %, else NOT_OSCILLATING."""

from __future__ import annotations

from typing import Any

import numpy as np

from stiction import Assessment, Verdict


def analyze(op: Any, pv: Any, *, ts: float, kp: float | None = None, delay: float = 0.0,
            process: str = "self-regulating", op_range: tuple[float, float] = (0.0, 100.0),
            k: float = 1.99) -> Assessment:
    amp = float(np.ptp(op))
    if amp > 10.0:
        return Assessment(Verdict.STICTION, f"fake: OP swings {amp:.1f} %", oscillating=True,
                          period_s=100.0 * ts, stiction_index=0.8, fd=amp / 400.0,
                          fs=None, jump=amp / 1200.0)
    return Assessment(Verdict.NOT_OSCILLATING, f"fake: OP swings {amp:.1f} %")
