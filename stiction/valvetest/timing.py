"""The response times of one step: dead time, T63, T86 and overshoot (ISA-75.25.01 terms).

Definitions (ISA-75.25.01; EnTech, Control Valve Dynamic Specification v3.0, 1998), each
measured from the step (the first sample whose OP shows the new value):

* dead time: until the response first leaves its level by more than noise (three
  standard deviations of the smoothed response) and more than 5 % of its final change;
* T63 and T86: until it first reaches 63.2 % and 86.5 % of its final change, dead time
  included (as ISA-75.25.01's T86);
* overshoot: how far it went past the final change, as a fraction of that change (the
  noise's three standard deviations taken off first, so noise alone reads 0).

The step's response is the recording less the fitted response to every *other* step
(:mod:`.response`), so a tail of the step before does not count. For an integrating PV the
response is PV's rate (a local slope over seven samples). Times are interpolated between
samples; a recording at sample time ``ts`` cannot place the step itself closer than
``ts``. From PV the times are those of the valve and the process together; from the
valve's position they are the valve's own.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray
from .holds import Holds
from .response import Moves

__all__ = ["Timing", "step_timing"]

RATE_HALF = 3  # samples each side of the local slope (integrating PV)


@dataclasses.dataclass(frozen=True)
class Timing:
    dead_time_s: float | None = None
    t63_s: float | None = None
    t86_s: float | None = None
    overshoot: float | None = None


def _smoothed(r: FloatArray, noise: float, ts: float, integrating: bool
              ) -> tuple[FloatArray, float]:
    """The step's response, smoothed (three samples), or its rate; and its noise SD."""
    if integrating:
        h = RATE_HALF
        w = np.arange(-h, h + 1, dtype=np.float64)
        w /= float(w @ w) * ts
        rate = np.convolve(r, w[::-1], mode="same")
        rate[:h], rate[-h:] = rate[h], rate[-h - 1]
        return rate, noise * float(np.sqrt(np.sum(w * w)))
    out = r.copy()
    out[1:-1] = (r[:-2] + r[1:-1] + r[2:]) / 3.0
    return out, noise / np.sqrt(3.0)


def _crossing(s: FloatArray, level: float, ts: float) -> float | None:
    """Time (s after sample 0) ``s`` first reaches ``level``, interpolated; None if never."""
    hit = np.flatnonzero(s >= level)
    if hit.size == 0:
        return None
    m = int(hit[0])
    if m == 0:
        return 0.0
    frac = (level - s[m - 1]) / (s[m] - s[m - 1]) if s[m] != s[m - 1] else 1.0
    return max(0.0, (m - 1 + float(frac)) * ts)


def step_timing(y: FloatArray, moves: Moves, holds: Holds, k: int, *, ts: float,
                integrating: bool) -> Timing:
    """Dead time, T63, T86 and overshoot of step ``k`` (>= 1) of ``holds``."""
    j = k - 1
    size = float(moves.size[j])
    lo, hi = int(holds.step_at[k]), int(holds.end[k])
    if size == 0 or hi - lo < 3:
        return Timing()
    other = moves.model - size * moves.columns[:, j]
    before = max(lo - 1, 0)
    r = (y - other)[before:hi]
    good = np.isfinite(r)
    if not good.any():
        return Timing()
    r = np.interp(np.arange(r.size), np.flatnonzero(good), r[good])  # gaps bridged
    s, sd = _smoothed(r, moves.noise, ts, integrating)
    s = s if size > 0 else -s
    mag = abs(size)
    shift = (lo - before) * ts  # sample 0 of s is this long before the step
    leave = max(3.0 * sd, 0.05 * mag)
    times = [_crossing(s, f, ts) for f in (leave, 0.632 * mag, 0.865 * mag)]
    dead, t63, t86 = (None if x is None else max(0.0, x - shift) for x in times)
    peak = float(np.max(s[lo - before:]))
    return Timing(dead, t63, t86, max(0.0, peak - mag - 3.0 * sd) / mag)
