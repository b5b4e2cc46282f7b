"""What every detector receives and gives: one :class:`Window` in, one
:class:`~stiction.Evidence` out.

A detector is a pure function of a :class:`Window`: the clean window (equal-length, finite
OP and PV, gaps filled by the quality gates) and what the gates measured on it (the cycle
the shape tests look at, the noise levels). It returns its :class:`~stiction.Evidence`
(``test`` its registry name, ``value`` its headline statistic or None when it could not
run, ``vote`` +1 stiction / -1 not stiction / 0 cannot tell, ``note`` one phrase), or, when
its fit also serves the sizing (the ellipse's band, the fitted valve), the fit itself: any
object with an ``evidence()`` method (:class:`Fitted`).

Detectors never import each other nor the diagnosis; what they share lives below them in
:mod:`stiction.signal`. :mod:`.registry` lists them.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Protocol, runtime_checkable

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.arrays import percentiles
from ..signal.cycle import Cycle

__all__ = ["LEVELS", "NO_CYCLE", "Detector", "Fitted", "Window", "evidence_of"]

LEVELS = (2.0, 50.0, 98.0)
"""The percentiles of :attr:`Window.levels`."""

NO_CYCLE = "no cycle to look at"
"""The note of a test that needs a cycle on a window without one."""


@dataclasses.dataclass(frozen=True)
class Window:
    """One clean window and what the gates measured on it: every detector's input."""

    op: FloatArray
    pv: FloatArray
    ts: float  # sample time, s
    integrating: bool  # the process integrates (a level): PV ramps where OP would step
    cycle: Cycle  # the oscillation and the signals as the shape tests see them
    noise: tuple[float, float]  # white-noise SDs of OP and PV (signal.noise.noise_sd)

    @property
    def period(self) -> float | None:
        """The cycle's period in samples; None without a cycle (or one under a sample)."""
        p = self.cycle.period
        return p if p is not None and p >= 1.0 else None

    @functools.cached_property
    def levels(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """OP's and PV's 2nd, 50th and 98th percentiles (``np.percentile``), computed once
        for the tests that scale by them (Kano's stuck intervals, the stick-slip episodes)."""
        return percentiles(self.op, LEVELS), percentiles(self.pv, LEVELS)


@runtime_checkable
class Fitted(Protocol):
    """A detector's full result, where more than its evidence is used (for the sizing)."""

    def evidence(self) -> Evidence: ...


@dataclasses.dataclass(frozen=True)
class Detector:
    """One registered test: ``name`` is its evidence's ``test``, ``run`` the function,
    ``reference`` the publication it implements."""

    name: str
    run: Callable[[Window], Evidence | Fitted]
    reference: str


def evidence_of(result: Evidence | Fitted) -> Evidence:
    """The evidence a detector gave, from its evidence or its fit."""
    return result if isinstance(result, Evidence) else result.evidence()
