"""The verdict from the valve's travel, where its position was read.

:func:`stiction.quantify.travel.measure_travel` measures the valve against OP; here its
finding replaces what OP and PV suggest, since it is a measurement of the valve itself:

* the valve **sticks**: ``stiction``, the reason saying "measured from the valve's travel",
  sized by the band and slip (``band``/``band_op``, ``jump``) and fd, fs in He's terms; the
  confidence is the share of the valve's reversals that showed the band (1.0 when all did);
* it **follows** OP: ``no_stiction`` whatever PV does (an oscillation is then from
  elsewhere), except where OP and PV found the loop calm (``not_oscillating`` stays: there
  is no oscillation to explain); the confidence is again the share of sticking reversals;
* it does **not respond** (OP ran, the valve held): ``valve_not_responding``;
* the travel cannot tell (no usable position, a calm loop the valve never reversed in): the
  OP/PV diagnosis;
* the position did not show it is the valve's (:func:`stiction.quantify.travel.
  shown_as_position`: it moves against OP, in another scale, or lags OP by more than two
  samples; or it held while OP ran and PV moved, a frozen reading of a valve that moves):
  the OP/PV diagnosis, never a verdict from it.

A position is evidence only after it has shown it is one (issue 35: an inverted one read
``no_stiction`` 0.0 on a very sticky valve, PV wired in as the position ``stiction`` 1.0 on a
good one). Every case adds one :class:`~stiction.Evidence`, ``travel`` (value: the band in
OP units, vote +1 sticks / -1 follows / 0), whose note begins with the source that decided
the verdict: ``decided by the valve's travel`` or ``decided by OP and PV``; and sets
``Assessment.position_use`` (``used``, ``could_not_tell``, ``not_a_position``). Where the
position was not used the reason ends by saying so and why.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._assessment import Assessment, Evidence, Verdict
from .._validate import FloatArray
from ..quantify.travel import FOLLOWS, NOT_A_POSITION, NOT_RESPONDING, STICKS, Travel
from ..signal.noise import noise_sd
from .responding import HELD_NOISE, M

__all__ = ["BY_OP_PV", "BY_TRAVEL", "MEASURED", "NOT_USED", "apply_travel", "frozen_reading"]

MEASURED = "measured from the valve's travel"
BY_TRAVEL = "decided by the valve's travel"
BY_OP_PV = "decided by OP and PV"
NOT_USED = "The valve's position was not used"


def frozen_reading(travel: Travel, pv: FloatArray) -> Travel:
    """``travel`` as :data:`NOT_A_POSITION` where it says the valve did not respond while PV,
    over the same samples, moved beyond its noise (its ``M``-sample means spread more than
    ``HELD_NOISE`` noise SDs, :mod:`.responding`'s test of a PV held): a valve that moved PV
    moved, so the reading is frozen; else ``travel`` unchanged."""
    if travel.status != NOT_RESPONDING:
        return travel
    tail = pv[travel.still_from:]
    means = tail[: (tail.size // M) * M].reshape(-1, M).mean(axis=1)
    sd = noise_sd(pv)
    if means.size < 2 or float(np.ptp(means)) <= HELD_NOISE * sd:
        return travel
    return dataclasses.replace(travel, status=NOT_A_POSITION, note=(
        f"not used as the valve's position: it held while OP ran and PV moved "
        f"{np.ptp(means):.3g} ({np.ptp(means) / sd:.0f} of its noise SDs) over the same "
        f"{tail.size} samples (a frozen reading of a valve that moves)"))


def _evidence(a: Assessment, travel: Travel, source: str) -> tuple[Evidence, ...]:
    vote = {STICKS: 1, FOLLOWS: -1}.get(travel.status, 0)
    return (*a.evidence, Evidence("travel", travel.band, vote, f"{source}: {travel.note}"))


def apply_travel(a: Assessment, travel: Travel, *, span: float | None, k: float
                 ) -> Assessment:
    """``a`` (the OP/PV assessment) as the valve's travel decides it (module doc); a
    ``travel`` not yet checked against PV passes :func:`frozen_reading` first."""
    if not travel.decides:
        use = "not_a_position" if travel.status == NOT_A_POSITION else "could_not_tell"
        note = travel.note.removeprefix("not used as the valve's position: ")
        sep = " " if a.reason.endswith(".") else ". "
        return dataclasses.replace(a, evidence=_evidence(a, travel, BY_OP_PV),
                                   reason=f"{a.reason}{sep}{NOT_USED}: {note}.",
                                   position_use=use)
    return dataclasses.replace(_decided(a, travel, span=span, k=k), position_use="used")


def _decided(a: Assessment, travel: Travel, *, span: float | None, k: float) -> Assessment:
    if travel.status == STICKS:
        return _sticks(a, travel, span=span, k=k)
    if travel.status == FOLLOWS and a.verdict != Verdict.NOT_OSCILLATING:
        cause = (" The oscillation is then from elsewhere (a load, the tuning, another loop)."
                 if a.oscillating else "")
        reason = (f"no_stiction, {MEASURED}: {travel.note} (confidence of stiction "
                  f"{travel.share_sticking:.2f}, the share of reversals that stuck).{cause}")
        return Assessment(Verdict.NO_STICTION, reason, oscillating=a.oscillating,
                          period_s=a.period_s, stiction_index=a.stiction_index,
                          warnings=a.warnings, confidence=travel.share_sticking,
                          evidence=_evidence(a, travel, BY_TRAVEL))
    if travel.status == NOT_RESPONDING:
        return Assessment(Verdict.VALVE_NOT_RESPONDING,
                          f"valve not responding, {MEASURED}: {travel.note}.",
                          oscillating=a.oscillating, period_s=a.period_s,
                          stiction_index=a.stiction_index, warnings=a.warnings,
                          evidence=_evidence(a, travel, BY_TRAVEL))
    return dataclasses.replace(a, evidence=_evidence(a, travel, BY_OP_PV))  # calm: OP/PV's


def _sticks(a: Assessment, travel: Travel, *, span: float | None, k: float) -> Assessment:
    """``stiction`` sized from the travel."""
    assert travel.band is not None
    assert travel.slip is not None
    assert travel.fd is not None
    assert travel.fs is not None
    scale, unit = (1.0, "OP units") if span is None else (span / 100.0, "% of span")

    def frac(x: float) -> float | None:
        return None if span is None else x / span

    band, slip = travel.band / scale, travel.slip / scale
    reason = (f"stiction, confidence {travel.share_sticking:.2f}, {MEASURED}: after each "
              f"reversal OP travels {band:.3g} {unit} before the valve moves (the band: dead "
              f"band plus stick band), then it jumps {slip:.3g} (the slip); {travel.sticking} "
              f"of {travel.reversals} reversals stuck. Size: fd {travel.fd / scale:.3g}, fs "
              f"{travel.fs / scale:.3g} {unit} (He's model, K {k:g}).")
    if span is None:
        reason += " Give op_range for sizes in % of span."
    return Assessment(
        Verdict.STICTION, reason, oscillating=a.oscillating, period_s=a.period_s,
        stiction_index=a.stiction_index, fd=frac(travel.fd), fs=frac(travel.fs),
        jump=frac(travel.slip), fd_op=travel.fd, fs_op=travel.fs, warnings=a.warnings,
        confidence=travel.share_sticking, evidence=_evidence(a, travel, BY_TRAVEL),
        band=frac(travel.band), band_op=travel.band)
