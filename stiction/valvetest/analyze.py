"""``analyze_step_test``: a step test's recording in, the valve's dead band, resolution, slip
and per-step response out (:class:`StepTestReport`).

The path: OP split into holds and steps (:mod:`.holds`, or refused as no step test); the
response identified on the largest steps and every step's share fitted at once, with the
settling at the start and without the disturbed holds (:mod:`.response`); each step read
as moved, not moved or unreadable (:mod:`.reading`); the valve's travel is that share over
the process gain (PV: ``kp`` where given, else read from the moves), or the share itself
(position); dead band, resolution and slip from the steps that could be read
(:mod:`.bands`); the response times of every step that moved (:mod:`.timing`). Sizes are
in OP units, or % of span with ``op_range``. Every figure is physical (never negative,
inside the bounds reported with it) or absent, and the notes say why.
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
from .reading import Z_MOVED, Reading, read_steps
from .response import Dynamics, Moves, fit_dynamics, fit_moves
from .timing import step_timing

__all__ = ["SOURCES", "StepResult", "StepTestDetails", "StepTestReport", "analyze_step_test",
           "step_test_details"]

SOURCES = ("pv", "position")
PROCESSES = ("auto", "self-regulating", "integrating")
SHOWN_UNREAD = 3  # disturbed holds named in the notes (the rest counted)


@dataclasses.dataclass(frozen=True)
class StepResult:
    """One step: when, how far OP went, whether and how far the valve followed (``moved``
    None: the step cannot be read, ``why``), and its response times (None where it did
    not move or the hold ended first)."""

    time_s: float
    op_step: float
    moved: bool | None
    travel: float | None
    gain: float | None  # travel / op_step
    dead_time_s: float | None
    t63_s: float | None
    t86_s: float | None
    overshoot: float | None  # fraction of the step's final change
    why: str | None = None  # why the step cannot be read


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
    dead_time_s: float | None  # of the fitted response (None: no step moved the valve)
    lag_s: float | None
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
    reading: Reading

    @property
    def moved(self) -> np.ndarray:
        return self.reading.moved


def analyze_step_test(op: ArrayLike, response: ArrayLike, ts: float, *, source: str = "pv",
                      process: str = "auto", op_range: tuple[float, float] | None = None,
                      kp: float | None = None) -> StepTestReport:
    """Analyse a step test: ``op`` and ``response`` (PV, or the valve position with
    ``source="position"``, in OP's units) sampled every ``ts`` s, gaps as NaN. ``process``
    (a PV's): ``auto`` tells self-regulating from integrating by the fit. ``op_range``
    (OP at 0 and 100 % of span) gives sizes in % of span. ``kp`` (a PV's): the process
    gain, PV units per OP unit (per s for an integrating process), through which PV's
    changes are read as the valve's travel; without it the gain is read from the moves.
    Raises :class:`~stiction.valvetest.NotAStepTest` for a recording that is no step
    test (OP never steps or moves continuously; a response frozen at one value)."""
    return step_test_details(op, response, ts, source=source, process=process,
                             op_range=op_range, kp=kp).report


def _check(op: ArrayLike, response: ArrayLike, ts: float, *, source: str, process: str,
           op_range: tuple[float, float] | None, kp: float | None
           ) -> tuple[FloatArray, FloatArray, float]:
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
    if kp is not None:
        if source == "position":
            raise ParameterError("kp", "is PV's process gain: the valve position is read "
                                 "in OP's units, without it")
        if float(v.finite("kp", kp)) == 0.0:
            raise ParameterError("kp", "must not be 0")
    if np.isfinite(y).sum() < 10:
        raise NotAStepTest(f"the {_name(source)} holds fewer than 10 numbers")
    return o, y, v.positive_scalar("ts", ts)


def _name(source: str) -> str:
    return "valve position" if source == "position" else "PV"


def _not_frozen(y: FloatArray, source: str) -> None:
    """NotAStepTest for a response that holds one value throughout."""
    good = y[np.isfinite(y)]
    if float(np.ptp(good)) == 0.0:
        raise NotAStepTest(f"the {_name(source)} holds one value ({good[0]:.6g}) in all "
                           f"{good.size} samples: the signal is frozen (a failed "
                           "transmitter, a tag that no longer updates, a historian's "
                           "compression wider than the test's changes), or the valve never "
                           "moved and the signal shows no noise at all; nothing to read "
                           "either way: check the signal's trend, and export it with every "
                           "change")


def step_test_details(op: ArrayLike, response: ArrayLike, ts: float, *, source: str = "pv",
                      process: str = "auto", op_range: tuple[float, float] | None = None,
                      kp: float | None = None) -> StepTestDetails:
    """:func:`analyze_step_test` with what it was read from."""
    o, y, ts = _check(op, response, ts, source=source, process=process, op_range=op_range,
                      kp=kp)
    holds = split_holds(o)
    _not_frozen(y, source)
    kinds = ((False,) if source == "position" or process == "self-regulating"
             else (True,) if process == "integrating" else (False, True))
    dyn = fit_dynamics(y, holds, ts, kinds)
    moves = fit_moves(y, holds, ts, dyn)
    reading = read_steps(holds, moves, source=source, kp=kp)
    moved, gain = reading.moved, reading.gain
    steps = holds.op_steps
    # the valve's travel, signed as OP: a position is in OP's units; a PV's share over the
    # process gain (its sign included: a PV that falls as the valve opens)
    travel = moves.size / gain if gain and source == "pv" else moves.size
    scale = 100.0 / (op_range[1] - op_range[0]) if op_range is not None else 1.0
    b = bands(holds.level, moved, travel, reading.unread)
    results = []
    for k in range(1, holds.n):
        j = k - 1
        tm = (step_timing(y, moves, holds, k, ts=ts, integrating=dyn.integrating)
              if moved[j] else None)
        tr = float(travel[j])
        results.append(StepResult(
            float(holds.step_at[k] * ts), float(steps[j]) * scale,
            None if reading.unread[j] else bool(moved[j]), tr * scale,
            tr / float(steps[j]) if moved[j] else None,
            tm.dead_time_s if tm else None, tm.t63_s if tm else None,
            tm.t86_s if tm else None, tm.overshoot if tm else None, reading.why[j]))
    notes = (*_start_and_disturbed(holds, moves, ts, dyn, source), *reading.notes,
             *_unread(results), *b.notes)
    report = _report(b, scale=scale, source=source, dyn=dyn, gain=gain, steps=results,
                     notes=notes, op_range=op_range)
    return StepTestDetails(report, holds, dyn, moves, reading)


def _start_and_disturbed(holds: Holds, moves: Moves, ts: float, dyn: Dynamics,
                         source: str) -> tuple[str, ...]:
    """Notes on the settling at the start and the disturbed holds, where there are any."""
    out = []
    name = "the valve position" if source == "position" else "PV"
    if abs(moves.settle) > Z_MOVED * moves.settle_se:
        how = ("its rate" if dyn.integrating
               else f"it moved {moves.settle:+.3g} more after the first sample")
        out.append(f"{name} was still settling when the recording began ({how}): read with "
                   "its settling, not as a step (wait for it to settle before the first "
                   "step)")
    hit = np.flatnonzero(moves.disturbed)
    if hit.size:
        at = ", ".join(f"{holds.start[h] * ts:.0f} s" for h in hit[:SHOWN_UNREAD])
        out.append(f"{name} moved while OP held still in {hit.size} hold"
                   f"{'s' if hit.size > 1 else ''} (from {at}): a disturbance, not the "
                   "valve; those holds are left out, and the steps beside them are not read")
    return tuple(out)


def _unread(results: list[StepResult]) -> tuple[str, ...]:
    """One note on the steps that cannot be read: how many, and why (each kind of reason
    once, with its first step)."""
    bad = [r for r in results if r.moved is None]
    if not bad:
        return ()
    kinds: dict[str, list[StepResult]] = {}
    for r in bad:
        kinds.setdefault(str(r.why).split(":")[0], []).append(r)
    why = "; ".join(f"{len(rs)} {rs[0].why} (the first at {rs[0].time_s:.0f} s)"
                    if len(rs) > 1 else f"at {rs[0].time_s:.0f} s: {rs[0].why}"
                    for rs in kinds.values())
    return (f"{len(bad)} of {len(results)} steps cannot be read, so they bound nothing: "
            f"{why}",)


def _report(b: Bands, *, scale: float, source: str, dyn: Dynamics, gain: float | None,
            steps: list[StepResult], notes: tuple[str, ...],
            op_range: tuple[float, float] | None) -> StepTestReport:
    moved = any(s.moved for s in steps)  # else the fitted response is noise's
    def sized(x: float | None) -> float | None:
        return None if x is None else x * scale

    process = ("valve position" if source == "position"
               else "integrating" if dyn.integrating else "self-regulating")
    return StepTestReport(
        "% of span" if op_range is not None else "OP units", source, process,
        sized(b.deadband.value), (b.deadband.low * scale, b.deadband.high * scale),
        sized(b.resolution.value), (b.resolution.low * scale, b.resolution.high * scale),
        sized(b.slip), None if gain is None else gain / scale,
        max(dyn.theta, 0.0) if moved else None, dyn.tau if moved else None, tuple(steps),
        notes)
