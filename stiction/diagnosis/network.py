"""The OP-PV shape network as one more source of evidence in :func:`stiction.analyze`
(issue 36).

The network (:mod:`.shape`: trained on simulated loops only, lab/shape/README.md) reads a
clean window's OP and PV over a few of its cycles, the cycle ``analyze`` found (it is not
looked up again). Its logit goes through the Platt map fitted on held-out simulation
(:func:`.shape.calibrated`): the probability that the window is a sticky valve where sticky
windows are as common as there (about one in five). That probability is the evidence's
``value``, and its vote, as the evidence gate (:mod:`.gate`) reads votes:

- **+1** at or above ``meta["threshold"]`` (0.690: 90 % of the calls right on held-out
  simulation; on the 80 plant records, never trained on, 16 of 35 sticky records found and
  none of the 45 others);
- **-1** below ``meta["band_low"]`` (0.155: the highest score under which at most 5 % of the
  held-out simulated windows were sticky);
- **0** in between, and on a cycle shorter than :data:`.shape.MIN_PERIOD` samples, which
  the network cannot read (:attr:`.shape.ShapeScore.readable`; value None), or one the
  fast-cycle test found: the shared Tennessee Eastman records at 2.2 samples a cycle are
  such.

The score is one window's, the simulation's calibration alone (no site adaptation, which
needs the other windows of a site: :mod:`.adapt`). The weights are read once per process
(:func:`.shape.load` is cached).
"""

from __future__ import annotations

import dataclasses

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.cycle import Cycle
from . import shape
from .evidence import Findings
from .gate import FAST_READERS

__all__ = ["NAME", "WHAT", "Reading", "added", "read", "thresholds", "vote_of"]

NAME = "shape_net"
"""The evidence's ``test``."""
WHAT = "the OP-PV shape network"
"""What the reason calls it."""


@dataclasses.dataclass(frozen=True)
class Reading:
    """The network on one window: ``probability`` (Platt) and ``vote``; ``score`` the raw
    reading (None where the cycle is too fast to read)."""

    probability: float | None
    vote: int
    note: str
    score: shape.ShapeScore | None = None

    def evidence(self) -> Evidence:
        """Test :data:`NAME`, value the Platt probability (None: not read)."""
        return Evidence(NAME, self.probability, self.vote, self.note)

    @property
    def logit(self) -> float | None:
        return None if self.score is None else self.score.logit


def thresholds() -> tuple[float, float]:
    """(band_low, threshold) of the shipped weights (Platt probabilities)."""
    meta = shape.load().meta
    lo, hi = meta["band_low"], meta["threshold"]
    if not isinstance(lo, float) or not isinstance(hi, float):
        raise ValueError(f"the weights' meta has no thresholds: {lo!r}, {hi!r}")
    return lo, hi


def vote_of(probability: float) -> int:
    """+1 at or above the threshold, -1 below ``band_low``, else 0 (module doc)."""
    lo, hi = thresholds()
    return 1 if probability >= hi else -1 if probability < lo else 0


def read(op: FloatArray, pv: FloatArray, cycle: Cycle) -> Reading:
    """The network on a clean window with its cycle (module doc)."""
    period = cycle.period
    if period is not None and period < shape.MIN_PERIOD:
        return Reading(None, 0, f"a cycle of {period:.1f} samples is too fast for {WHAT} "
                                f"(it reads {shape.MIN_PERIOD:.0f} or more)")
    net = shape.load()
    s = shape.score(op, pv, period=period, find=False, net=net)
    p = float(shape.calibrated(net, s.logit))
    return Reading(p, vote_of(p), f"{WHAT}: {p:.2f}", s)


def added(found: Findings, op: FloatArray, pv: FloatArray, cycle: Cycle) -> Findings:
    """``found`` with the network's evidence after the registered tests' (its reading in
    ``results[NAME]``). Where a test made for cycles too fast for their shape found such a
    cycle (:data:`.gate.FAST_READERS` voting either way), the network does not read the
    window: the cycle ``find_cycle`` missed is there, too fast for it (the Tennessee Eastman
    reactor valve logged every 600 s: no cycle found, the fast-cycle test's two levels)."""
    fast = sorted(e.test for e in found.evidence if e.test in FAST_READERS and e.vote != 0)
    r = Reading(None, 0, f"{fast[0]} found a cycle too fast for {WHAT}") if fast else \
        read(op, pv, cycle)
    return dataclasses.replace(found, evidence=(*found.evidence, r.evidence()),
                               results={**found.results, NAME: r})
