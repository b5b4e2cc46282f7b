"""The evidence that a member of a group is its source, and the ranking it makes.

Four kinds of evidence, each with its reference and each in the JSON ranking:

- **its own verdict** (``verdict``, ``confidence``): the per-loop analysis of its window
  (:func:`stiction.analyze`). A loop whose own window says ``stiction`` is strong evidence
  that its valve makes the cycle.
- **its own valve** (``valve_gain``, ``kano``, ``episodes``; :attr:`MemberEvidence.valve`):
  a sticky valve in the loop's own path, OP -> valve -> process -> PV, explains PV better
  than a linear valve (the Hammerstein fit of :mod:`stiction.detectors.hammerstein` at the
  group's period, through the process path only: ``valve_gain``, the gain in the share of
  PV explained), PV stands still while OP ramps (Kano's stuck-interval index) and the
  window holds stick-slip episodes. In a follower PV is a load its own linear valve works
  against: a sticky valve adds nothing.
- **direction** (``flow``, ``lag_s``; :mod:`.direction`): Granger causality on the
  band-passed cycle, the net flow from this loop to the group's other leading signals
  (Yuan and Qin 2014; Bauer et al. 2007: the source's cycle is seen first); the phase lag
  of its fundamental behind the group's source (or top candidate), reported.
- **nonlinearity** (``nli``; :mod:`.nonlinearity`): the surrogate-data nonlinearity index
  of its cycle (Thornhill, Cox and Paulonis 2003; Thornhill 2005), highest at the source.

Also reported: how strongly the loop carries the cycle (``strength``) and the harmonic
content of its OP and PV at the group's frequency (``harmonics``: in closed loop a
follower's controller removes more of the fundamental than of the harmonics, so it is
reported, never ranked).

:attr:`MemberEvidence.score` ranks the candidates: ``valve + confidence + FLOW_WEIGHT *
flow + NLI_WEIGHT * min(nli, 3)`` (each part 0 when not measured). Which of them names a
source is decided in :mod:`.decide`. Where the top candidate is the outer loop of a declared
cascade and its inner loop is in the group, the inner loop takes its place: the outer loop's
"valve" is the inner loop.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._assessment import Assessment
from .._validate import FloatArray
from ..detectors.hammerstein import hammerstein_test
from .spectra import Spectra

__all__ = ["FLOW_WEIGHT", "NEAR_TIE", "NLI_WEIGHT", "SOURCE_CONFIDENCE", "SOURCE_SCORE",
           "MemberEvidence", "harmonics", "member_evidence", "rank"]

SOURCE_SCORE = 0.3
"""The valve score (:attr:`MemberEvidence.valve`) from which a loop's own valve names it the
source, with a per-loop confidence of at least ``SOURCE_CONFIDENCE``."""
SOURCE_CONFIDENCE = 0.5
NEAR_TIE = 0.05
"""Scores this close count as a tie, broken by the per-loop confidence."""
HARMONICS = (2, 3, 4, 5)
STICK_SLIP_WEIGHT = 0.3
FLOW_WEIGHT = 2.0
"""Weight of the net Granger flow (nats) in the rank's score: a source leads its followers
by 0.2-1.5 on the project's plants, a follower trails by as much."""
NLI_WEIGHT = 0.1
"""Weight of the nonlinearity index (capped at 3) in the score: on the project's plants the
followers' cycles are often as nonlinear as the source's (their lags are short against the
period), so it weighs little; it decides where a cycle enters from outside."""


@dataclasses.dataclass(frozen=True)
class MemberEvidence:
    """Why a member loop is, or is not, its group's source (module doc)."""

    loop: str
    strength: float  # share of its OP's or PV's power in the group's band
    valve_gain: float | None  # sticky over linear valve, share of PV (None: no fit)
    kano: float  # Kano's stuck-interval index of its window (0: none, or not known)
    episodes: int  # stick-slip episodes in its window
    confidence: float | None  # its per-loop confidence of stiction
    harmonics: float  # harmonic power over the fundamental's, the larger of OP and PV
    verdict: str | None = None  # its own per-loop verdict
    flow: float | None = None  # net Granger flow to the group's leading signals (None: not
    # measured: not a leading candidate)
    nli: float | None = None  # nonlinearity index of its cycle (None: not measured)
    lag_s: float | None = None  # phase lag of its fundamental behind the source's, s
    signal: str = "pv"  # which of its signals carries the cycle most strongly: "op", "pv"

    @property
    def valve(self) -> float:
        """The own-valve evidence: ``valve_gain + kano + STICK_SLIP_WEIGHT * min(episodes,
        10) / 10``."""
        gain = 0.0 if self.valve_gain is None else self.valve_gain
        return gain + self.kano + STICK_SLIP_WEIGHT * min(self.episodes, 10) / 10.0

    @property
    def called(self) -> bool:
        """Its own window says ``stiction``."""
        return self.verdict == "stiction"

    @property
    def valve_named(self) -> bool:
        """Its own valve is evidence enough to name it a source."""
        return self.valve >= SOURCE_SCORE and self.confidence is not None and \
            self.confidence >= SOURCE_CONFIDENCE

    @property
    def score(self) -> float:
        """The rank's key (module doc)."""
        flow = 0.0 if self.flow is None else self.flow
        nli = 0.0 if self.nli is None or not math.isfinite(self.nli) else min(self.nli, 3.0)
        return self.valve + (self.confidence or 0.0) + FLOW_WEIGHT * flow + \
            NLI_WEIGHT * max(nli, 0.0)

    @property
    def prescore(self) -> float:
        """The score without direction and nonlinearity (which are measured for the leading
        candidates only)."""
        return self.valve + (self.confidence or 0.0)

    def note(self) -> str:
        """The evidence in words, for a reason."""
        parts = []
        if self.verdict is not None:
            conf = "" if self.confidence is None else f" at {self.confidence:.2f}"
            parts.append(f"its own window says {self.verdict}{conf}")
        parts.append("no valve fit" if self.valve_gain is None else
                     f"a sticky valve explains {self.valve_gain:.0%} more of its PV than a "
                     "linear one")
        if self.flow is not None:
            parts.append(f"Granger net flow {self.flow:+.2f}")
        if self.nli is not None:
            parts.append(f"nonlinearity index {self.nli:.1f}")
        parts.append(f"carries the cycle at {self.strength:.0%} of its power")
        return ", ".join(parts)


def harmonics(spec: Spectra, row: int, f0: float, width: float) -> float:
    """Power at 2-5 times ``f0`` over the power at ``f0`` (bands of half-width ``width``),
    each less the noise floor (the spectrum's median bin)."""
    power, freqs = spec.power[row], spec.freqs
    floor = float(np.median(power)) if power.size else 0.0

    def band(fc: float) -> float:
        sel = (freqs >= fc - width) & (freqs <= fc + width)
        return float(power[sel].sum()) - floor * int(np.count_nonzero(sel))

    fundamental = band(f0)
    if fundamental <= 0:
        return 0.0
    return sum(max(band(k * f0), 0.0) for k in HARMONICS) / fundamental


def member_evidence(loop: str, op: FloatArray, pv: FloatArray, *, ts: float, period: float,
                    integrating: bool, strength: float, assessment: Assessment | None,
                    harmonic: float, signal: str = "pv", fit: bool = True) -> MemberEvidence:
    """The own evidence of one member loop at its group's ``period`` (samples): its valve
    (``fit``: the Hammerstein fit too) and its verdict (direction and nonlinearity are
    added for the leading candidates)."""
    gain = None
    if fit:
        res = hammerstein_test(op, pv, ts=ts, period=period, integrating=integrating)
        if res.stats is not None and math.isfinite(res.stats.level_process):
            gain = float(res.stats.level_process)
    conf = None if assessment is None else assessment.confidence
    verdict = None if assessment is None else str(assessment.verdict)
    values = {} if assessment is None else {e.test: e.value for e in assessment.evidence}
    kano = values.get("kano") or 0.0
    episodes = int(values.get("stick_slip") or 0)
    return MemberEvidence(loop, strength, gain, float(kano), episodes, conf, harmonic,
                          verdict, signal=signal)


def rank(members: list[MemberEvidence], cascades: dict[str, str]) -> list[MemberEvidence]:
    """Members best first: by score, near-ties by per-loop confidence; a declared
    outer loop on top yields to its inner loop when that is a member."""
    ordered = sorted(members, key=lambda e: (-e.score, -(e.confidence or 0.0), e.loop))
    if len(ordered) > 1 and ordered[0].score - ordered[1].score < NEAR_TIE and \
            (ordered[1].confidence or 0.0) > (ordered[0].confidence or 0.0):
        ordered[0], ordered[1] = ordered[1], ordered[0]
    inner = cascades.get(ordered[0].loop)
    names = [e.loop for e in ordered]
    if inner in names:
        k = names.index(inner)
        ordered.insert(0, ordered.pop(k))
    return ordered
