"""Setpoint steps are not valve jumps: where the window's setpoint (SP) is known, the stretch
of it that is judged.

A setpoint step moves PV on purpose, and the controller moves OP to make it: to the tests a
PV that jumps after OP stood ramping looks like a valve breaking free (plant tag 2411FIC20102,
``../shared/data/plant-stictiongpt``: every record holds one or two SP steps, and the
stick-slip test saw "OP ramped +2.13 with PV still, then PV jumped +2.45" where PV followed
SP from 103 to 107). Given SP, :func:`steady_stretch` finds the **moves** of SP and the
window is judged on the longest **stretch between them** (the samples after a move up to the
next one), never across a move, where that stretch holds at least ``KEEP`` of the window
(else the window is judged whole and the reason says a step is in it):

* a **move** is a run of samples in which SP changes (by more than ``TOLERANCE`` of its
  magnitude: the float dust of an export is no move), changes closer than ``MERGE`` samples
  joined (a step entered as a ramp over a few samples is one move), whose net change is at
  least ``MIN_MOVE`` of PV's 2-98 % range (a nudge too small to move PV visibly is no step);
* the stretch after a move starts at the first sample at the new SP, so the loop's response
  to the step stays in it: a sticky valve's stuck phase and jump in answer to the step is
  evidence, but PV's jump across the step itself, with no stuck phase before it in the
  stretch, is not read as a slip;
* a setpoint that changes in more than ``MOVING_SHARE`` of the samples moves continuously (a
  cascade's secondary loop, a ramped SP): there are no steps to cut at, the window is judged
  whole and a warning says so.

The error PV - SP was the alternative: it takes the step out of PV but puts it into the error
at the step, with OP's answer after it, a jump the slip test reads the same way; cutting
keeps every test's view of an undisturbed loop. A window without SP (``sp=None``) is judged
whole, as always. The reason of the assessment says which samples were judged and where SP
moved (:meth:`SetpointCut.sentence`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray

__all__ = ["KEEP", "MERGE", "MIN_MOVE", "MOVING_SHARE", "TOLERANCE", "SetpointCut",
           "steady_stretch"]

TOLERANCE = 1e-6
"""SP changes smaller than this share of its largest magnitude are float dust, not moves."""
MERGE = 3
"""SP changes at most this many samples apart belong to one move."""
MIN_MOVE = 0.05
"""A move smaller than this share of PV's 2-98 % range is not a step."""
MOVING_SHARE = 0.2
"""SP changing in more than this share of the samples moves continuously: no cut."""
KEEP = 0.9
"""The longest steady stretch must hold at least this share of the window to be judged
alone (a step in the window's first or last tenth is cut off); a shorter one leaves the
window judged whole, the reason naming the moves in it. Cutting shorter stretches cost the
real records their cycles (issue 36: on the 80 plant records, every one with SP steps, the
stretches read 'valve not responding' or 'no oscillation' for 15 of the 35 sticky records:
4 of 35 found as a batch; whole, 21 of 35 with none of the 45 others called; a bar of 0.6
found 14 and called 1, 0.8 found 20 and called 1). The shape network learned windows with
setpoint steps in them, and a verdict of stiction needs a test or the network to back it
(:mod:`.gate`): a step alone is not read as a sticky valve."""


@dataclasses.dataclass(frozen=True)
class SetpointCut:
    """The stretch ``[start, stop)`` of a window of ``samples`` judged, and the SP moves
    ``(first, last, sp_before, sp_after)``: ``first`` the first sample at a changed SP,
    ``last`` the first sample at its final value; or, with ``moving`` set, a setpoint that
    moves continuously (the whole window, no moves listed)."""

    start: int
    stop: int
    samples: int
    moves: tuple[tuple[int, int, float, float], ...] = ()
    moving: float | None = None  # share of samples in which SP changed, where it moves
    short: bool = False  # the longest steady stretch is under KEEP of the window: judged whole

    @property
    def cuts(self) -> bool:
        """Whether the window is cut (else judged whole)."""
        return self.stop - self.start < self.samples

    def sentence(self, ts: float) -> str:
        """What was judged and why, in the window's time (``ts`` s a sample)."""
        from .enough import duration  # noqa: PLC0415

        if self.moving is not None:
            return (f"the setpoint moves in {self.moving:.0%} of the samples (a cascade's or "
                    "a ramped setpoint): the window is judged whole, and a PV jump that "
                    "followed SP may read as the valve's")
        said = ", ".join(f"{a:.4g} -> {b:.4g} at sample {first}"
                         for first, _, a, b in self.moves)
        if self.short:
            return (f"the setpoint moved ({said}) and its longest steady stretch holds under "
                    f"{KEEP:.0%} of the window, too little to judge alone: the window is "
                    "judged whole, and a PV jump that followed SP may read as the valve's")
        return (f"judged on samples {self.start}-{self.stop - 1} "
                f"({duration((self.stop - self.start) * ts)} of "
                f"{duration(self.samples * ts)}), the longest stretch between setpoint "
                f"moves ({said}): a setpoint step is not the valve's jump")


def _moves(sp: FloatArray, min_move: float) -> list[tuple[int, int, float, float]]:
    """The SP moves (module doc)."""
    tol = TOLERANCE * max(float(np.max(np.abs(sp))), 1e-300)
    changed = np.flatnonzero(np.abs(np.diff(sp)) > tol) + 1  # first samples at a new value
    out: list[tuple[int, int, float, float]] = []
    k = 0
    while k < changed.size:
        j = k
        while j + 1 < changed.size and changed[j + 1] - changed[j] <= MERGE:
            j += 1
        first, last = int(changed[k]), int(changed[j])
        before, after = float(sp[first - 1]), float(sp[last])
        if abs(after - before) >= min_move:
            out.append((first, last, before, after))
        k = j + 1
    return out


def steady_stretch(sp: FloatArray, pv: FloatArray) -> SetpointCut | None:
    """The stretch of the window to judge, given its setpoint ``sp`` (module doc); None
    where SP never moved (or holds no number): the whole window. ``sp`` and ``pv``: equal
    lengths; NaN in SP (a sample the export lacks) holds the last SP before it."""
    n = sp.size
    ok = np.isfinite(sp)
    if not ok.any():
        return None
    idx = np.where(ok, np.arange(n), 0)
    np.maximum.accumulate(idx, out=idx)
    first_ok = int(np.argmax(ok))
    filled = sp[idx]
    filled[:first_ok] = sp[first_ok]
    tol = TOLERANCE * max(float(np.max(np.abs(filled))), 1e-300)
    changes = int(np.count_nonzero(np.abs(np.diff(filled)) > tol))
    if changes == 0:
        return None
    if changes > MOVING_SHARE * n:
        return SetpointCut(0, n, n, moving=changes / n)
    finite = pv[np.isfinite(pv)]
    span = float(np.percentile(finite, 98) - np.percentile(finite, 2)) if finite.size else 0.0
    moves = _moves(filled, MIN_MOVE * span)
    if not moves:
        return None
    bounds = [0, *[b for first, last, _, _ in moves for b in (first, last)], n]
    stretches = [(bounds[i], bounds[i + 1]) for i in range(0, len(bounds), 2)]
    start, stop = max(stretches, key=lambda s: s[1] - s[0])
    if stop - start < KEEP * n:
        return SetpointCut(0, n, n, tuple(moves), short=True)
    return SetpointCut(start, stop, n, tuple(moves))
