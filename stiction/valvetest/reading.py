"""Which steps moved the valve, which did not, and which cannot be read; the process gain.

A valve moves only the way its OP step went (for every friction model here, and for a
real valve: the net force grows only that way), so a step's share of the response
(:mod:`.response`), signed as the step went and as the process turns a move into PV (the
sign of the process gain), is read as an operator reads the trend:

* **moved**: the response went the step's way by more than :data:`Z_MOVED` standard
  errors (the noise around that step) and more than :data:`FLOOR` of the largest move
  (the fit's misfit grows with it);
* **did not move**: it stayed further below what a step followed in full would give
  (the OP step times the process gain) than that margin;
* **cannot be read** (``unread``, with the reason): neither of the two (a step whose full
  response is within the noise around it; every step that did not move the valve where
  none did and no ``kp`` says what a followed step shows), a response *against* the step
  beyond the noise (something else moved PV), or a disturbed hold beside the step
  (:data:`.response.DISTURBED_SD`). Such a step is neither a move nor a lower bound of
  one (:mod:`.bands`).

The process gain (response units per OP unit; per s for an integrating PV) is ``kp`` where
given; otherwise read from the moves (:func:`read_gain`); 1 for the valve's position,
which is in OP's units.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from .._validate import FloatArray
from .holds import Holds
from .response import Moves

__all__ = ["FLOOR", "Z_MOVED", "Reading", "read_gain", "read_steps"]

Z_MOVED = 4.0  # standard errors a step's share must exceed to count as a move
FLOOR = 0.01  # ... and this share of the largest move
GAIN_DISAGREES = 1.5  # ratio between the steps' gain and a given kp worth a note


@dataclasses.dataclass(frozen=True)
class Reading:
    """Per step (index k - 1): moved, or unread (with why); neither: it did not move. The
    gain (signed) the travels are read through, and notes."""

    moved: NDArray[np.bool_]
    unread: NDArray[np.bool_]
    why: tuple[str | None, ...]
    gain: float | None
    notes: tuple[str, ...] = ()


def _sign(holds: Holds, moves: Moves, kp: float | None) -> float:
    """How the response turns a move the way of OP: kp's sign where given, else the
    sign most of the clearest shares (the largest against their standard error) agree on."""
    if kp is not None:
        return float(np.sign(kp))
    steps = holds.op_steps
    z = np.abs(moves.size) / np.maximum(moves.se, 1e-300)
    top = np.argsort(-z, kind="stable")[:6]
    top = top[(z[top] > Z_MOVED) & (steps[top] != 0)]
    if top.size == 0:
        return 1.0
    return 1.0 if float(np.median(moves.size[top] / steps[top])) >= 0 else -1.0


def read_steps(holds: Holds, moves: Moves, *, source: str, kp: float | None) -> Reading:
    """The reading of every step (see the module docstring)."""
    steps = holds.op_steps
    sign = _sign(holds, moves, kp if source == "pv" else None)
    along = moves.size * np.sign(steps) * sign  # the share the way the step went
    strong = along > Z_MOVED * moves.se
    floor = FLOOR * float(np.max(along[strong], initial=0.0))
    margin = np.maximum(Z_MOVED * moves.se, floor)
    beside = np.zeros(steps.size, bool)
    if moves.disturbed.size:
        beside = moves.disturbed[:-1] | moves.disturbed[1:]  # the hold before or after
    moved = (along > margin) & (steps != 0) & ~beside

    def still(gain: float | None) -> NDArray[np.bool_]:
        # without a gain, what a step followed in full shows is unknown: none is sure
        full = np.abs(steps) * abs(gain) if gain is not None else np.zeros(steps.size)
        out: NDArray[np.bool_] = ~moved & (along < full - margin) & (along > -margin) & ~beside
        return out

    notes: list[str] = []
    big = _single_steps(steps, moves.size, moved)
    if source == "position":
        gain: float | None = 1.0
    elif kp is not None:
        gain = kp
        found, _ = read_gain(holds.level, moves.size, moved, still(big))
        if found is not None and not (1 / GAIN_DISAGREES <= found / kp <= GAIN_DISAGREES):
            notes.append(f"the steps read a process gain of {found:.3g} per OP unit where "
                         f"kp is {kp:.3g}: check kp (every travel from PV is read through "
                         "it)")
    else:
        gain, gain_notes = read_gain(holds.level, moves.size, moved, still(big))
        notes += gain_notes
    unread = ~moved & ~still(gain)
    if not moved.any() and unread.all():
        notes = []  # the reason of every step says it
    full = None if gain is None else np.abs(steps) * abs(gain)
    why = tuple(_why(k, along, margin, full, beside) if unread[k] else None
                for k in range(steps.size))
    return Reading(moved, unread, why, gain, tuple(notes))


def _single_steps(steps: FloatArray, size: FloatArray, moved: NDArray[np.bool_]
                  ) -> float | None:
    """The gain of the largest steps that moved the valve, each alone (a first reading:
    low by the dead band they may include)."""
    if not moved.any():
        return None
    sel = moved & (np.abs(steps) >= 0.5 * np.abs(steps[moved]).max())
    return float(np.median(size[sel] / steps[sel]))


def _why(k: int, along: FloatArray, margin: FloatArray, full: FloatArray | None,
         beside: NDArray[np.bool_]) -> str:
    if beside[k]:
        return "a disturbance during the hold before or after it"
    if along[k] <= -margin[k]:
        return "the response went against the step: something else moved it"
    if full is None:
        return ("without the process gain (no step moved the valve, no kp given), a step "
                "the valve did not follow cannot be told from one lost in the noise: give kp")
    return (f"within the noise: a step followed in full moves the response "
            f"{full[k]:.2g}, the noise around it {margin[k]:.2g}")


def read_gain(levels: FloatArray, size: FloatArray, moved: NDArray[np.bool_],
              quiet: NDArray[np.bool_] | None = None) -> tuple[float | None, tuple[str, ...]]:
    """Response per OP unit. Between two moves of the valve in the same direction, with no
    reversal of OP between them, a valve that follows OP with lost motion (He's model with
    K = 1, Choudhury's, Kano's) travels exactly as far as OP did, whether it stuck on the
    way or not: the later move's response over that OP travel, the median of the larger
    half of such pairs; only pairs whose steps between surely did not move the valve
    (``quiet``: no move hidden there)."""
    steps = np.diff(levels)
    pairs: list[tuple[float, float]] = []  # (OP travel, response)
    last: int | None = None
    for k in np.flatnonzero(moved):
        if last is not None:
            between = steps[last:k + 1]
            hidden = quiet is not None and not np.all(quiet[last + 1:k])
            if not hidden and np.all(np.sign(between[between != 0]) == np.sign(steps[k])):
                pairs.append((float(levels[k + 1] - levels[last + 1]), float(size[k])))
        last = int(k)
    if pairs:
        travel = np.array([p[0] for p in pairs])
        sel = np.abs(travel) >= 0.5 * np.abs(travel).max()
        return float(np.median(np.array([p[1] for p in pairs])[sel] / travel[sel])), ()
    single = _single_steps(steps, size, moved)
    if single is not None:
        return single, (
            "the valve never moved twice the same way: the process gain (and every travel "
            "from PV) is read from single steps, which may include the dead band",)
    return None, ("no step moved the valve: its band is wider than the OP travel the test "
                  "made (or the response does not show the valve); a larger test is the "
                  "crew's decision",)
