"""``analyze_step_test``: a step test's recording in, the valve's dead band, resolution, slip
and per-step response out (:class:`StepTestReport`).

The path: OP split into holds and steps (:mod:`.holds`, or refused as no step test); the
response identified on the largest steps and every step's share fitted at once
(:mod:`.response`); a step *moved* the valve when its share exceeds four standard errors
and 1 % of the largest share (the fit's misfit grows with it); the valve's travel is that
share over the process gain (PV), or the share itself (position); dead band, resolution
and slip from which
steps moved (:mod:`.bands`); the response times of every step that moved
(:mod:`.timing`). Sizes are in OP units, or % of span with ``op_range``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray
from .bands import Bands, bands
from .holds import Holds, NotAStepTest, split_holds
from .response import Dynamics, Moves, fit_dynamics, fit_moves
from .timing import step_timing

__all__ = ["SOURCES", "StepResult", "StepTestDetails", "StepTestReport", "analyze_step_test",
           "step_test_details"]

SOURCES = ("pv", "position")
PROCESSES = ("auto", "self-regulating", "integrating")
Z_MOVED = 4.0  # standard errors a step's share must exceed to count as a move
FLOOR = 0.01  # ... and this share of the largest move


@dataclasses.dataclass(frozen=True)
class StepResult:
    """One step: when, how far OP went, whether and how far the valve followed, and its
    response times (None where it did not move or the hold ended first)."""

    time_s: float
    op_step: float
    moved: bool
    travel: float | None
    gain: float | None  # travel / op_step
    dead_time_s: float | None
    t63_s: float | None
    t86_s: float | None
    overshoot: float | None  # fraction of the step's final change


@dataclasses.dataclass(frozen=True)
class StepTestReport:
    """The valve's step test; sizes in ``unit`` (``% of span`` or ``OP units``)."""

    unit: str
    source: str  # pv or position: what the valve's response was read from
    process: str  # self-regulating, integrating, or valve position
    deadband: float | None
    deadband_bounds: tuple[float, float]
    resolution: float | None
    resolution_bounds: tuple[float, float]
    slip: float | None
    gain: float | None  # response units per OP unit of a step the valve followed
    dead_time_s: float  # of the fitted response (identification)
    lag_s: float
    steps: tuple[StepResult, ...]
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        for key in ("deadband_bounds", "resolution_bounds"):
            out[key] = [None if not math.isfinite(x) else x for x in out[key]]
        out["notes"] = list(self.notes)
        return out


@dataclasses.dataclass(frozen=True)
class StepTestDetails:
    """The report and what it was read from (for a plot)."""

    report: StepTestReport
    holds: Holds
    dynamics: Dynamics
    moves: Moves
    moved: np.ndarray


def analyze_step_test(op: ArrayLike, response: ArrayLike, ts: float, *, source: str = "pv",
                      process: str = "auto",
                      op_range: tuple[float, float] | None = None) -> StepTestReport:
    """Analyse a step test: ``op`` and ``response`` (PV, or the valve position with
    ``source="position"``, in OP's units) sampled every ``ts`` s, gaps as NaN. ``process``
    (a PV's): ``auto`` tells self-regulating from integrating by the fit. ``op_range``
    (OP at 0 and 100 % of span) gives sizes in % of span. Raises
    :class:`~stiction.valvetest.NotAStepTest` for a recording that is no step test."""
    return step_test_details(op, response, ts, source=source, process=process,
                             op_range=op_range).report


def _check(op: ArrayLike, response: ArrayLike, ts: float, *, source: str, process: str,
           op_range: tuple[float, float] | None) -> tuple[FloatArray, FloatArray, float]:
    o, y = v.as_float_array("op", op).reshape(-1), v.as_float_array("response", response)
    y = y.reshape(-1)
    if o.size != y.size:
        raise ParameterError("response", f"must have as many samples as op ({y.size} != "
                             f"{o.size})")
    if source not in SOURCES:
        raise ParameterError("source", f"must be one of {', '.join(SOURCES)}, was {source!r}")
    if process not in PROCESSES:
        raise ParameterError("process", f"must be one of {', '.join(PROCESSES)}, "
                             f"was {process!r}")
    if op_range is not None and not (len(op_range) == 2 and op_range[1] > op_range[0]):
        raise ParameterError("op_range", f"must be (lo, hi) with hi > lo, was {op_range!r}")
    if np.isfinite(y).sum() < 10:
        raise NotAStepTest(f"the {'valve position' if source == 'position' else 'PV'} "
                           "holds fewer than 10 numbers")
    return o, y, v.positive_scalar("ts", ts)


def step_test_details(op: ArrayLike, response: ArrayLike, ts: float, *, source: str = "pv",
                      process: str = "auto",
                      op_range: tuple[float, float] | None = None) -> StepTestDetails:
    """:func:`analyze_step_test` with what it was read from."""
    o, y, ts = _check(op, response, ts, source=source, process=process, op_range=op_range)
    holds = split_holds(o)
    kinds = ((False,) if source == "position" or process == "self-regulating"
             else (True,) if process == "integrating" else (False, True))
    dyn = fit_dynamics(y, holds, ts, kinds)
    moves = fit_moves(y, holds, ts, dyn)
    steps = holds.op_steps
    # a move must stand out of the fit's misfit too, which grows with the largest move
    floor = max(FLOOR * float(np.max(np.abs(moves.size))), 1e-9 * float(np.nanmax(np.abs(y))))
    moved = (np.abs(moves.size) > Z_MOVED * moves.se) & (np.abs(moves.size) > floor)
    gain, notes = _gain(holds.level, moves.size, moved)
    # the valve's travel, signed as OP: a position is in OP's units; a PV's share over the
    # process gain (its sign included: a PV that falls as the valve opens)
    travel = moves.size / gain if gain and source == "pv" else moves.size
    scale = 100.0 / (op_range[1] - op_range[0]) if op_range is not None else 1.0
    b = bands(holds.level, moved, travel)
    results = []
    for k in range(1, holds.n):
        tm = (step_timing(y, moves, holds, k, ts=ts, integrating=dyn.integrating)
              if moved[k - 1] else None)
        tr = float(travel[k - 1])
        results.append(StepResult(
            float(holds.step_at[k] * ts), float(steps[k - 1]) * scale, bool(moved[k - 1]),
            tr * scale, tr / float(steps[k - 1]) if moved[k - 1] else None,
            tm.dead_time_s if tm else None, tm.t63_s if tm else None,
            tm.t86_s if tm else None, tm.overshoot if tm else None))
    report = _report(b, scale=scale, source=source, dyn=dyn, gain=gain, steps=results,
                     notes=(*notes, *b.notes), op_range=op_range)
    return StepTestDetails(report, holds, dyn, moves, moved)


def _gain(levels: FloatArray, size: FloatArray, moved: np.ndarray
          ) -> tuple[float | None, tuple[str, ...]]:
    """Response per OP unit. Between two moves of the valve in the same direction, with no
    reversal of OP between them, a valve that follows OP with lost motion (He's model with
    K = 1, Choudhury's, Kano's) travels exactly as far as OP did, whether it stuck on the
    way or not: the later move's response over that OP travel, the median of the larger
    half of such pairs."""
    steps = np.diff(levels)
    pairs: list[tuple[float, float]] = []  # (OP travel, response)
    last: int | None = None
    for k in np.flatnonzero(moved):
        if last is not None:
            between = steps[last:k + 1]
            if np.all(np.sign(between[between != 0]) == np.sign(steps[k])):
                pairs.append((float(levels[k + 1] - levels[last + 1]), float(size[k])))
        last = int(k)
    if pairs:
        travel = np.array([p[0] for p in pairs])
        sel = np.abs(travel) >= 0.5 * np.abs(travel).max()
        return float(np.median(np.array([p[1] for p in pairs])[sel] / travel[sel])), ()
    if moved.any():
        sel = moved & (np.abs(steps) >= 0.5 * np.abs(steps[moved]).max())
        return float(np.median(size[sel] / steps[sel])), (
            "the valve never moved twice the same way: the process gain (and every travel "
            "from PV) is read from single steps, which may include the dead band",)
    return None, ("no step moved the valve",)


def _report(b: Bands, *, scale: float, source: str, dyn: Dynamics, gain: float | None,
            steps: list[StepResult], notes: tuple[str, ...],
            op_range: tuple[float, float] | None) -> StepTestReport:
    def sized(x: float | None) -> float | None:
        return None if x is None else x * scale

    process = ("valve position" if source == "position"
               else "integrating" if dyn.integrating else "self-regulating")
    return StepTestReport(
        "% of span" if op_range is not None else "OP units", source, process,
        sized(b.deadband.value), (b.deadband.low * scale, b.deadband.high * scale),
        sized(b.resolution.value), (b.resolution.low * scale, b.resolution.high * scale),
        sized(b.slip), None if gain is None else gain / scale, max(dyn.theta, 0.0), dyn.tau,
        tuple(steps), notes)
