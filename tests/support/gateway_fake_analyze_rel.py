"""A deterministic stand-in for stiction.analyze in reliability tests that check plumbing
(reload, state file): the verdict says how many samples the window had."""

from __future__ import annotations

from typing import Any

from stiction import Assessment, Verdict


def analyze(op: Any, pv: Any, *, ts: float, kp: float | None = None, delay: float = 0.0,
            process: str = "self-regulating", op_range: tuple[float, float] = (0.0, 100.0),
            k: float = 1.99) -> Assessment:
    return Assessment(Verdict.NOT_OSCILLATING, f"fake: {len(op)} samples",
                      stiction_index=0.25, period_s=float(len(op)))
