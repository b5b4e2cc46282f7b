"""Literal and analytic signals the stage tests share (signal, detectors, quantify)."""

from __future__ import annotations

import numpy as np
from scipy import signal

T = np.arange(3000.0)
SINE = np.sin(2 * np.pi * T / 200.0)
TRIANGLE = signal.sawtooth(2 * np.pi * T / 200.0, width=0.5)


def first_order(u: np.ndarray, tau: float) -> np.ndarray:
    a = np.exp(-1.0 / tau)
    return signal.lfilter([0.0, 1.0 - a], [1.0, -a], u, zi=[a * u[0]])[0]


def square_vp(n: int, half: int, double: bool) -> tuple[np.ndarray, np.ndarray]:
    """VP (%) alternating 48/52 every ``half`` samples; ``double``: each move in two steps
    of 2 %, the second 60 samples after the first."""
    vp = np.full(n, 50.0)
    jumps = np.arange(100, n, half)
    level = 48.0
    for k, j in enumerate(jumps):
        level = 52.0 if k % 2 == 0 else 48.0
        if double:
            vp[j:] = level - (2.0 if k % 2 == 0 else -2.0)
            vp[j + 60:] = level + (2.0 if k % 2 == 0 else -2.0)
        else:
            vp[j:] = level
    return vp, jumps
