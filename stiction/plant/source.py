"""Which member of a group is its source: the loop whose own valve explains its PV.

An oscillation born at a sticky valve travels as a load into other loops; each of those
answers it with a good valve. So among the loops that share a cycle, the source is the one
where a sticky valve in the loop's own path, OP -> valve -> process -> PV, explains PV
better than a linear valve does, and where PV stands still while OP ramps; in a follower
PV is a load its own (linear) valve works against, and a sticky valve adds nothing.
:func:`member_evidence` fits both valves to each member at the group's period (the
Hammerstein fit of :mod:`stiction.detectors.hammerstein`, through the process path only)
and reads the gain in the share of PV explained (``valve_gain``); from the loop's own
assessment it takes Kano's stuck-interval index and the count of stick-slip episodes.
Candidates are ranked by ``score = valve_gain + kano + STICK_SLIP_WEIGHT * min(episodes,
10) / 10``; near-ties go to the larger per-loop confidence of stiction. (``python -m bench
plantwide`` prints the source's rank by the score, by the valve gain alone and by the
harmonics, side by side: on the project's plant scenarios the score ranks it first most
often, the harmonics least.)

The ranking's top is named the group's source only with evidence of its own: a score of at
least ``SOURCE_SCORE`` and a per-loop confidence of at least ``SOURCE_CONFIDENCE``.
Otherwise no loop is named: the cycle enters from outside (a utility header, the weather,
a loop or unit the gateway does not read) or its source cannot be told.

Also reported, as evidence, not used for the rank: how strongly the loop carries the cycle
(its share of power in the band) and the harmonic content of its OP and PV at the group's
frequency (Thornhill, Cox and Paulonis 2003 rank by nonlinearity; but in closed loop a
follower's controller removes more of the fundamental than of the harmonics, so its PV
can look more distorted than the source's, and on the project's plant scenarios the
harmonics rank the source first in only 16-56 % of the groups). Lead and lag were tried as
well (the timing of each PV's fastest moves against the group's) and left out: noisy on the
plant scenarios, and a closed loop turns the phase of what it rejects by up to a quarter
period either way.

Where the top candidate is the outer loop of a declared cascade and its inner loop is in
the group, the inner loop takes its place: the outer loop's "valve" is the inner loop.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._assessment import Assessment
from .._validate import FloatArray
from ..detectors.hammerstein import hammerstein_test
from .spectra import Spectra

__all__ = ["NEAR_TIE", "SOURCE_CONFIDENCE", "SOURCE_SCORE", "MemberEvidence", "harmonics",
           "member_evidence", "named_source", "rank"]

SOURCE_SCORE = 0.3
"""The score from which the top candidate is named the source (plant scenarios, both
seeds: 69 of 108 true sources on top of their group reach it with the confidence below, 1
of 67 tops of groups whose cycle came from outside or from a tuning problem, 1 of 38 tops
that were not the source)."""
SOURCE_CONFIDENCE = 0.5
"""Per-loop confidence of stiction the named source needs as well."""
NEAR_TIE = 0.05
"""Valve gains this close count as a tie, broken by the per-loop confidence."""
HARMONICS = (2, 3, 4, 5)
STICK_SLIP_WEIGHT = 0.3


@dataclasses.dataclass(frozen=True)
class MemberEvidence:
    """Why a member loop is, or is not, its group's source."""

    loop: str
    strength: float  # share of its OP's or PV's power in the group's band
    valve_gain: float | None  # sticky over linear valve, share of PV (None: no fit)
    kano: float  # Kano's stuck-interval index of its window (0: none, or not known)
    episodes: int  # stick-slip episodes in its window
    confidence: float | None  # its per-loop confidence of stiction
    harmonics: float  # harmonic power over the fundamental's, the larger of OP and PV

    @property
    def score(self) -> float:
        """The rank's key: the own-valve evidence (module doc)."""
        gain = 0.0 if self.valve_gain is None else self.valve_gain
        return gain + self.kano + STICK_SLIP_WEIGHT * min(self.episodes, 10) / 10.0

    def note(self) -> str:
        gain = "no valve fit" if self.valve_gain is None else \
            f"a sticky valve explains {self.valve_gain:.0%} more of its PV than a linear one"
        conf = "" if self.confidence is None else f", per-loop confidence {self.confidence:.2f}"
        return f"{gain}{conf}, carries the cycle at {self.strength:.0%} of its power"


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
                    harmonic: float) -> MemberEvidence:
    """The evidence of one member loop at its group's ``period`` (samples)."""
    fit = hammerstein_test(op, pv, ts=ts, period=period, integrating=integrating)
    gain = None if fit.stats is None or not math.isfinite(fit.stats.level_process) \
        else float(fit.stats.level_process)
    conf = None if assessment is None else assessment.confidence
    values = {} if assessment is None else {e.test: e.value for e in assessment.evidence}
    kano = values.get("kano") or 0.0
    episodes = int(values.get("stick_slip") or 0)
    return MemberEvidence(loop, strength, gain, float(kano), episodes, conf, harmonic)


def _key(e: MemberEvidence) -> float:
    return e.score


def rank(members: list[MemberEvidence], cascades: dict[str, str]) -> list[MemberEvidence]:
    """Members best first: by score, near-ties by per-loop confidence; a declared
    outer loop on top yields to its inner loop when that is a member."""
    ordered = sorted(members, key=lambda e: (-_key(e), -(e.confidence or 0.0), e.loop))
    if len(ordered) > 1 and _key(ordered[0]) - _key(ordered[1]) < NEAR_TIE and \
            (ordered[1].confidence or 0.0) > (ordered[0].confidence or 0.0):
        ordered[0], ordered[1] = ordered[1], ordered[0]
    inner = cascades.get(ordered[0].loop)
    names = [e.loop for e in ordered]
    if inner in names:
        k = names.index(inner)
        ordered.insert(0, ordered.pop(k))
    return ordered


def named_source(top: MemberEvidence) -> bool:
    """Is the top candidate's own evidence enough to name it the source?"""
    return top.score >= SOURCE_SCORE and top.confidence is not None and \
        top.confidence >= SOURCE_CONFIDENCE
