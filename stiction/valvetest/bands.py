"""Dead band, resolution and slip from which steps moved the valve.

Definitions (ANSI/ISA-75.25.01, ISA-51.1; EnTech's Control Valve Dynamic Specification):

* **dead band**: the OP travel after a reversal through which the valve does not move:
  counted from the OP at which the valve last moved, in the direction back, up to the step
  that first moved it back. This is the whole band of a sticky valve (dead band plus stick
  band: S in Choudhury's and Kano's models, fs + fd in He's with K = 1).
* **resolution**: the smallest OP travel, without a reversal, that the valve follows:
  counted from the OP at which it last moved, onward (J in Choudhury's and Kano's models,
  fs - fd in He's with K = 1, K (fs - fd) with small steps for any K).
* **slip**: how far the valve jumps when it breaks free: its travel at a step that moved it
  onward after at least one step that did not (0 when it never stuck between moves).

Each move of the valve brackets one of the first two: between the furthest OP travel that
did not move it (since its last move) and the travel at the step that did; every step that
did not move it is a lower bound. The estimate lies in the bracket all moves agree on (so
its error is at most the step size there), 0 when the valve always followed the first step
and that step was the finest that could be read (the value is then below what the test
can see: ``bounds`` says how far). The resolution is the bracket's middle. The dead band
is read closer where the valve's travel is known: a valve with lost motion (He's model
with K = 1, Choudhury's, Kano's), moving again after a reversal, sits as far from OP on
the other side as before, so the OP travel to that move less the valve's travel is the
band's width without the stick band, and that plus the resolution is the dead band (kept
inside the bracket): exact between coarse steps too, and a valve that follows every step
reads 0.
Moves that disagree (the valve does not repeat itself, or noise took a move or made one)
give the median of their own brackets' middles instead, each weighted by how narrow its
bracket is, with a note.

Every figure is physical: a bracket runs from a travel of at least 0 to a larger one, so
the figure is never negative and always inside the bounds reported with it. Only steps
that could be read count: a step that cannot be (``unread``: within the noise, a
disturbance beside it) may have moved the valve or not, so the valve's reference (the OP
at its last move) is lost there and the next move starts afresh, without a bracket. A
move that contradicts the steps before it (the valve moved at a travel smaller than one
that did not move it, or at none at all) is not the valve's threshold: it brackets
nothing, and the reference is lost there too; the figures say how many. A valve that no
step moved (every step read) sat within its band over the whole test: the dead band is
at least half the OP range the test covered.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._validate import FloatArray

__all__ = ["Band", "Bands", "bands"]


@dataclasses.dataclass(frozen=True)
class Band:
    """One figure: its estimate (None: never measured) and the interval it lies in."""

    value: float | None
    low: float
    high: float  # inf: no move bounded it from above
    consistent: bool = True


@dataclasses.dataclass(frozen=True)
class Bands:
    deadband: Band
    resolution: Band
    slip: float | None
    notes: tuple[str, ...] = ()


@dataclasses.dataclass
class _Collect:
    lows: list[float] = dataclasses.field(default_factory=list)
    brackets: list[tuple[float, float]] = dataclasses.field(default_factory=list)

    def band(self, smallest: float, guesses: list[float] | None = None) -> Band:
        """The figure: the middle of the bracket all moves agree on, 0 below the finest
        step read (with ``guesses``, one a bracket: their median, kept inside it); the
        weighted median of the brackets' own points when they disagree."""
        lows = [*self.lows, *(lo for lo, _hi in self.brackets)]
        low = max(lows, default=0.0)
        if not self.brackets:
            return Band(None, low, math.inf)
        high = min(hi for _lo, hi in self.brackets)
        points = [min(max(g, lo), hi) for g, (lo, hi) in zip(guesses, self.brackets,
                                                                strict=True)] \
            if guesses else [(lo + hi) / 2.0 for lo, hi in self.brackets]
        if low < high or math.isclose(low, high):
            low = min(low, high)  # one figure, read twice in floating point
            if guesses:
                return Band(min(max(float(np.median(points)), low), high), low, high)
            below = low <= 0 and high <= smallest * (1 + 1e-9)  # under the finest step
            return Band(0.0 if below else (low + high) / 2.0, low, high)
        lo_all = min(lo for lo, _hi in self.brackets)
        hi_all = max(hi for _lo, hi in self.brackets)
        return Band(_weighted_median(points, self.brackets), lo_all, hi_all,
                    consistent=False)


def bands(levels: FloatArray, moved: np.ndarray, travel: FloatArray,
          unread: np.ndarray | None = None) -> Bands:
    """From the OP of each hold (``levels``), whether each step moved the valve and how
    far (``moved``, ``travel``: step k at index k - 1; a move goes the way its OP step
    went), and which steps could not be read (``unread``: neither moved nor not)."""
    op_steps = np.diff(levels)
    unread = np.zeros(op_steps.size, bool) if unread is None else np.asarray(unread, bool)
    dead, res = _Collect(), _Collect()
    slips: list[float] = []
    onward = 0  # moves onward (no reversal) after a first one
    back_breaks: list[tuple[float, float]] = []  # (valve travel, OP travel) at reversals
    ref: tuple[float, float] | None = None  # (OP at the last move, its direction)
    onward_max = back_max = 0.0
    stuck = contradictions = 0
    for k in range(1, levels.size):
        u, d = float(levels[k]), float(np.sign(op_steps[k - 1]))
        if unread[k - 1] or (moved[k - 1] and d == 0):
            ref = None  # the valve may have moved here, or not: its reference is lost
            continue
        progress = 0.0 if ref is None else (u - ref[0]) * ref[1]
        if not moved[k - 1]:
            if ref is not None:
                onward_max, back_max = max(onward_max, progress), max(back_max, -progress)
                stuck += 1
            continue
        if ref is not None:
            onward_move = d == ref[1]
            travelled = progress if onward_move else -progress
            if travelled <= (onward_max if onward_move else back_max):
                contradictions += 1  # moved at less travel than a step that did not
                ref = None
                continue
            if onward_move:
                res.brackets.append((onward_max, progress))
                dead.lows.append(back_max)
                onward += 1
                if stuck:
                    slips.append(abs(float(travel[k - 1])))
            else:
                dead.brackets.append((back_max, -progress))
                res.lows.append(onward_max)
                back_breaks.append((abs(float(travel[k - 1])), -progress))
        ref, onward_max, back_max, stuck = (u, d), 0.0, 0.0, 0
    if ref is not None:
        res.lows.append(onward_max)
        dead.lows.append(back_max)
    if not np.any(moved) and not unread.any():
        # never moved while OP ranged over the whole test: stuck within its band, which
        # is at least half that range wide either way
        dead.lows.append(float(np.ptp(levels)) / 2.0)
    read = np.abs(op_steps[~unread])  # the finest step that could be read
    smallest = float(read[read > 0].min()) if (read > 0).any() else 0.0
    resolution = res.band(smallest)
    # a valve with lost motion, once it moves after a reversal, sits as far from OP on
    # the other side as it sat before: OP travel less valve travel is that width, the
    # dead band less the stick band (the resolution). One reversal tells it even between
    # coarse steps; the bracket keeps it honest
    stick = resolution.value or 0.0
    deadband = dead.band(smallest, [op - v + stick for v, op in back_breaks])
    notes = []
    if contradictions:
        notes.append(f"{contradictions} move{'s' if contradictions > 1 else ''} of the valve "
                     "came at less OP travel than a step that had not moved it: noise or a "
                     "disturbance, not the valve's threshold; not used")
    for name, b in (("dead band", deadband), ("resolution", resolution)):
        if not b.consistent:
            notes.append(f"the {name} varied between moves ({b.low:.3g} .. {b.high:.3g}): "
                         "the median of the moves is reported")
    slip = _slip(slips, onward, back_breaks, deadband, bool(np.any(moved)))
    return Bands(deadband, resolution, slip, tuple(notes))


def _weighted_median(points: list[float], brackets: list[tuple[float, float]]) -> float:
    """Median of the brackets' points, each weighted by how narrow its bracket is (a move
    after a small step says more than one after a large step)."""
    mids = np.array(points)
    width = np.array([max(hi - lo, 1e-12) for lo, hi in brackets])
    order = np.argsort(mids)
    w = np.cumsum(1.0 / width[order])
    return float(mids[order][int(np.searchsorted(w, w[-1] / 2.0))])


def _slip(jumps: list[float], onward: int, back: list[tuple[float, float]],
          deadband: Band, moved: bool) -> float | None:
    """Median jump at onward breaks (0 if every onward move followed its step at once);
    without any onward move, the jump at reversals less the OP travel beyond the dead
    band."""
    if onward:
        return float(np.median(jumps)) if jumps else 0.0
    if back and deadband.value is not None:
        return float(np.median([max(0.0, v - (op - deadband.value)) for v, op in back]))
    return 0.0 if moved else None
