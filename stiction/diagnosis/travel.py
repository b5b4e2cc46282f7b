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
  OP/PV diagnosis unchanged.

Every case adds one :class:`~stiction.Evidence`, ``travel`` (value: the band in OP units,
vote +1 sticks / -1 follows / 0), whose note begins with the source that decided the
verdict: ``decided by the valve's travel`` or ``decided by OP and PV``.
"""

from __future__ import annotations

import dataclasses

from .._assessment import Assessment, Evidence, Verdict
from ..quantify.travel import FOLLOWS, NOT_RESPONDING, STICKS, Travel

__all__ = ["BY_OP_PV", "BY_TRAVEL", "MEASURED", "apply_travel"]

MEASURED = "measured from the valve's travel"
BY_TRAVEL = "decided by the valve's travel"
BY_OP_PV = "decided by OP and PV"


def _evidence(a: Assessment, travel: Travel, source: str) -> tuple[Evidence, ...]:
    vote = {STICKS: 1, FOLLOWS: -1}.get(travel.status, 0)
    return (*a.evidence, Evidence("travel", travel.band, vote, f"{source}: {travel.note}"))


def apply_travel(a: Assessment, travel: Travel, *, span: float | None, k: float
                 ) -> Assessment:
    """``a`` (the OP/PV assessment) as the valve's travel decides it (module doc)."""
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
    return dataclasses.replace(a, evidence=_evidence(a, travel, BY_OP_PV))


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
