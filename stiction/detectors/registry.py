"""Every detector the diagnosis runs, in the order their evidence is reported.

Adding a test: a module in this folder with a function ``Window -> Evidence`` (see
:mod:`.base`), and one line here. Until a model is trained with it, a new test's vote is
reported in ``Assessment.evidence`` but weighs nothing in the confidence.
"""

from __future__ import annotations

from . import bicoherence, ellipse, fastcycle, hammerstein, horch, kano, stickslip
from . import stiction_index as si
from .base import Detector

__all__ = ["DETECTORS", "names"]

DETECTORS: tuple[Detector, ...] = (
    Detector("si_op", si.detect_op, "He, Wang, Pottmann & Qin 2007"),
    Detector("si_pv", si.detect_pv, "He, Wang, Pottmann & Qin 2007"),
    Detector("bicoherence", bicoherence.detect, "Choudhury, Shah & Thornhill 2004"),
    Detector("horch", horch.detect, "Horch 1999; Horch 2000"),
    Detector("ellipse", ellipse.detect, "Choudhury, Shah & Thornhill 2006"),
    Detector("kano", kano.detect, "Kano, Maruta, Kugemoto & Shimizu 2004"),
    Detector("stick_slip", stickslip.detect, "stick-slip episodes without a cycle"),
    Detector("hammerstein", hammerstein.detect, "Srinivasan et al. 2005; He & Wang 2014"),
    Detector("fast_cycle", fastcycle.detect, "a limit cycle too fast for its shape"),
)


def names() -> tuple[str, ...]:
    """The registered tests' names, in order."""
    return tuple(d.name for d in DETECTORS)
