"""Capped, jittered exponential backoff for reconnecting to devices."""

from __future__ import annotations

import random

__all__ = ["Backoff"]


class Backoff:
    """Delays for successive reconnect attempts: ``uniform(0, min(cap, base·factor^n))``
    ("full jitter"), so many gateways or devices that lost a PLC at the same moment do not
    retry in lock-step. ``reset()`` after a success.
    """

    def __init__(self, base: float = 0.5, factor: float = 2.0, cap: float = 30.0,
                 rng: random.Random | None = None) -> None:
        if base <= 0:
            raise ValueError(f"`base` must be > 0, was {base}")
        if factor < 1:
            raise ValueError(f"`factor` must be >= 1, was {factor}")
        if cap < base:
            raise ValueError(f"`cap` must be >= base, was {cap}")
        self.base, self.factor, self.cap = base, factor, cap
        self.attempt = 0
        self._rng = rng or random.Random()

    def ceiling(self) -> float:
        """Upper bound of the next delay."""
        return min(self.cap, self.base * self.factor ** min(self.attempt, 64))

    def next_delay(self) -> float:
        delay = self._rng.uniform(0.0, self.ceiling())
        self.attempt += 1
        return delay

    def reset(self) -> None:
        self.attempt = 0
