"""The OP sequences of a step test: a few small steps around the operating point (what the
simulated PLC plays and what an operator on a running plant allows), and the thorough
staircase (a simulator's, or a valve on the bench).

:func:`operator_levels` steps OP as an operator does by hand (Ruel, Control 2000): for each
step size of ``steps`` (0.5, 1 and 2 % of span), ``count`` steps up, twice as many down
(a reversal, then through the operating point), ``count`` up again (back to it): 24 steps
in all, OP never further than ``count`` times the largest step (4 % of span) from where
it was. After each reversal OP travels back twice as far as it went (2, 4 and 8 % of
span), so a dead band up to 8 % shows, to within the step size; a larger one reads "more
than" that travel, and a larger test is the crew's decision, not the simulator's.

ISA-75.25.01 (Test Procedure for Control Valve Response Measurement from Step Inputs)
steps the input of a valve in manual: small steps up and down with reversals, then
larger ones (0.25 ... 10 % of span) whose responses give the dead time, T63 and T86.
:func:`step_test_levels` keeps that order but lays the small steps out as *staircases* whose steps
grow with the OP travel since the staircase began: each step is a tenth of that travel
(``growth``), at least ``min_step``. Wherever the valve first moves, the OP travel there
is bracketed to within a tenth of itself (or ``min_step``), from a dead band of 0.2 % of
span to one of 25 % in about 40 steps, without knowing the valve beforehand (Ruel's
manual test, Control 2000: small steps in one direction until the valve moves, then the
other way, is the same measurement done by hand).

It travels 25 % of span each way (197 steps): a simulator's test of the analysis over
dead bands from 0.2 to 25 %, not one to play on a running plant. Staircases, from
``op0``: up by ``reach`` (the valve's direction of travel is then known),
down by ``reach`` (a reversal: the dead band), down again (no reversal: the resolution and
the slip), up by ``reach`` twice (the other direction), then each of ``large`` as two steps
down and two up (the response times; the repeated step is the one whose travel gives the
gain). OP stays within ``op0 - reach .. op0 + reach``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray

__all__ = ["hold_series", "operator_levels", "staircase", "step_test_levels"]

OPERATOR_STEPS = (0.5, 1.0, 2.0)  # % of span, each way
OPERATOR_COUNT = 2  # steps each way before a reversal


def staircase(start: float, direction: int, *, reach: float, min_step: float,
              growth: float) -> list[float]:
    """OP levels of one staircase from ``start`` (excluded) ``reach`` in ``direction``
    (+1, -1): steps of ``max(min_step, growth * travel so far)``, the last one cut to end
    exactly at ``start + direction * reach``."""
    out: list[float] = []
    travel = 0.0
    while travel < reach - 1e-12:
        step = min(max(min_step, growth * travel), reach - travel)
        travel += step
        out.append(start + direction * travel)
    return out


def step_test_levels(op0: float = 50.0, *, reach: float = 25.0, min_step: float = 0.2,
                     growth: float = 0.1, large: Sequence[float] = (2.0, 5.0, 10.0)
                     ) -> FloatArray:
    """The hold levels of the whole sequence (see the module docstring), ``op0`` first;
    every value in OP units (% of span for the defaults)."""
    v.finite("op0", op0)
    reach_ = v.positive_scalar("reach", reach)
    min_step_ = v.positive_scalar("min_step", min_step)
    growth_ = float(v.non_negative("growth", growth))
    if min_step_ > reach_:
        raise ParameterError("min_step", f"must not exceed reach ({min_step} > {reach})")
    big = [v.positive_scalar("large", s) for s in large]
    if any(s > reach_ for s in big):
        raise ParameterError("large", f"steps must not exceed reach ({reach})")
    levels = [float(op0)]

    def stairs(direction: int) -> None:
        levels.extend(staircase(levels[-1], direction, reach=reach_, min_step=min_step_,
                                growth=growth_))

    for direction in (1, -1, -1, 1, 1):
        stairs(direction)
    for s in big:  # from op0 + reach: two down, two up
        for direction in (-1, -1, 1, 1):
            levels.append(levels[-1] + direction * s)
    return np.array(levels)


def operator_levels(op0: float = 50.0, *, steps: Sequence[float] = OPERATOR_STEPS,
                    count: int = OPERATOR_COUNT) -> FloatArray:
    """The hold levels of a few small steps around ``op0`` (see the module docstring),
    ``op0`` first and last; OP units (% of span for the defaults)."""
    v.finite("op0", op0)
    sizes = [v.positive_scalar("steps", s) for s in steps]
    if int(count) != count or count < 1:
        raise ParameterError("count", f"must be a positive whole number, was {count!r}")
    levels = [float(op0)]
    for size in sizes:
        for direction, n in ((1, count), (-1, 2 * count), (1, count)):
            levels.extend(levels[-1] + direction * size * np.arange(1, n + 1))
    return np.array(levels)


def hold_series(levels: FloatArray, hold: int) -> FloatArray:
    """One sample per row: each level held ``hold`` samples."""
    if int(hold) != hold or hold < 1:
        raise ParameterError("hold", f"must be a positive number of samples, was {hold!r}")
    return np.repeat(np.asarray(levels, dtype=np.float64), int(hold))
