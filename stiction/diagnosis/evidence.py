"""Every test on one window, each kept with its value and its vote.

One test sees one signature of a sticky valve and fails somewhere else; their agreement is
the evidence (``../shared/docs/detection-methods.md``). :func:`gather` builds the
:class:`~stiction.detectors.base.Window` every detector sees (the clean window, its cycle
from :func:`stiction.signal.cycle.find_cycle`, the noise levels) and runs every detector of
:data:`stiction.detectors.registry.DETECTORS`, in that order:

``si_op``, ``si_pv``
    He et al. (2007) curve fitting on OP and on PV (:mod:`stiction.detectors.stiction_index`).
``bicoherence``
    Choudhury et al. (2004) nonlinearity of PV (:mod:`stiction.detectors.bicoherence`).
``horch``
    Horch (1999, 2000) OP-PV cross-correlation or PV curvature (:mod:`stiction.detectors.horch`).
``ellipse``
    Choudhury et al. (2006) OP-PV pattern (:mod:`stiction.detectors.ellipse`).
``kano``
    Kano et al. (2004) stuck intervals (:mod:`stiction.detectors.kano`).
``stick_slip``
    Stick-slip episodes without a cycle (:mod:`stiction.detectors.stickslip`).
``hammerstein``
    The He-Wang valve in a Hammerstein fit against a linear valve
    (:mod:`stiction.detectors.hammerstein`).
``fast_cycle``
    A cycle too fast for its shape (:mod:`stiction.detectors.fastcycle`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .._assessment import Evidence
from .._validate import FloatArray
from ..detectors import registry
from ..detectors.base import Fitted, Window, evidence_of
from ..signal.cycle import Cycle, find_cycle
from ..signal.noise import noise_sd
from .quality import check_quality

__all__ = ["TESTS", "Findings", "gather", "gather_for_calibration"]

TESTS = registry.names()
"""The tests' names as registered when the package was loaded (:func:`registry.names` for
the current ones)."""


@dataclasses.dataclass(frozen=True)
class Findings:
    """Every test's evidence (registry order), its full result, and the noise levels."""

    evidence: tuple[Evidence, ...]
    results: Mapping[str, Evidence | Fitted]  # by test name: the fit where there is one
    noise: tuple[float, float]  # white-noise SDs of OP and PV (noise_sd), for the sizing too

    def vote(self, test: str) -> int:
        return next(e.vote for e in self.evidence if e.test == test)


def gather(op: FloatArray, pv: FloatArray, cycle: Cycle, *, integrating: bool, ts: float
           ) -> Findings:
    """Every registered test on a clean window (equal-length, finite)."""
    noise = (noise_sd(op), noise_sd(pv))  # once for the tests that need them
    window = Window(op, pv, ts, integrating, cycle, noise)
    results: dict[str, Evidence | Fitted] = {}
    for detector in registry.DETECTORS:
        results[detector.name] = detector.run(window)
    evidence = tuple(evidence_of(r) for r in results.values())
    wrong = [f"{name} gave {e.test!r}" for name, e in zip(results, evidence, strict=True)
             if e.test != name]
    if wrong:
        raise RuntimeError(f"a detector's evidence is not named as registered: {wrong}")
    return Findings(evidence, results, noise)


def gather_for_calibration(op: np.ndarray, pv: np.ndarray, *, ts: float,
                           integrating: bool = False) -> list[int]:
    """The votes of every test on a raw window as :func:`stiction.analyze` would see it
    (all zero when the window is bad data or a valve not responding)."""
    q = check_quality(np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64))
    if q.reason is not None or q.not_responding is not None:
        return [0] * len(registry.DETECTORS)
    cycle = find_cycle(q.op, q.pv, integrating=integrating)
    return [e.vote for e in gather(q.op, q.pv, cycle, integrating=integrating, ts=ts).evidence]
