"""How the development corpus labels a window, measured from the data (no tep-studio here).

A sticky valve's loop is labelled by what its valve did in the window, rebuilt from the
controller output with the model's own rule (``valve_command``, lab/sources/tep.py):
``stiction`` when it stuck and slipped (a stick-slip pattern: at least :data:`MIN_SLIPS`
slips, at least :data:`MIN_HOLD` samples between slips in the median), ``stiction-stuck``
when it hardly moved (fewer slips: OP wandered inside the band), ``stiction-masked`` when it
slipped at almost every sample (OP noise larger than the band dithers the valve: the loop
behaves as with a good valve).

Every other loop is labelled against the same loop in the same operating mode's normal
runs (the reference, :class:`Reference`): ``propagated`` when the sticky valve's cycle
reaches it (its OP or PV power in the band of that cycle grew :data:`CYCLE_RATIO` times
more over the reference's than its whole spectrum did: a loop that is only louder does not
count), or when the run has a sticky valve and no other disturbance and its OP or PV
SD is :data:`SD_RATIO` times the reference's; ``disturbance`` when a disturbance is active
and its OP or PV SD is :data:`SD_RATIO` times the reference's; else ``normal``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..windows.tep import LoopSummary

MIN_SLIPS = 6  # as stiction.scenarios.realistic keeps a sticky record
MIN_HOLD = 10  # samples (18 s at 1.8 s): a median rest shorter than this is dither
SD_RATIO = 1.5  # OP or PV SD over the largest of the normal runs': affected
CYCLE_RATIO = 4.0  # power in the sticky cycle's band over the largest normal: propagated
BAND = 1.5  # the cycle's band: f0 / BAND .. f0 * BAND
STICKY_CLASSES = ("stiction", "stiction-stuck", "stiction-masked")


@dataclasses.dataclass(frozen=True)
class ValveStats:
    """What a sticky valve did in a window (one value per controller sample)."""

    slips: int
    held: float  # share of samples at which the valve did not move
    median_hold: float  # median samples between slips (inf with < 2 slips)
    period_s: float  # 2 x mean time between slips: the stick-slip cycle (nan if none)

    @property
    def cause_class(self) -> str:
        if self.slips < MIN_SLIPS:
            return "stiction-stuck"
        if self.median_hold < MIN_HOLD:
            return "stiction-masked"
        return "stiction"


def valve_stats(command: np.ndarray, ts: float) -> ValveStats:
    moved = np.flatnonzero(np.diff(command) != 0.0)
    held = 1.0 - moved.size / max(command.size - 1, 1)
    gaps = np.diff(moved)
    hold = float(np.median(gaps)) if gaps.size else float("inf")
    period = 2.0 * float(np.mean(gaps)) * ts if gaps.size else float("nan")
    return ValveStats(int(moved.size), float(held), hold, period)


def band_power(freqs: np.ndarray, psd: np.ndarray, f0: float) -> float:
    """Power of ``psd`` (one-sided, on ``freqs``) from f0 / BAND to f0 * BAND."""
    sel = (freqs >= f0 / BAND) & (freqs <= f0 * BAND)
    return float(psd[sel].sum()) if sel.any() else 0.0


@dataclasses.dataclass(frozen=True)
class Reference:
    """A loop in its mode's normal runs: the largest SDs and, per frequency, the largest
    spectrum (a loop must exceed every normal run to count as affected)."""

    op_sd: float
    pv_sd: float
    freqs: np.ndarray
    op_psd: np.ndarray
    pv_psd: np.ndarray

    @classmethod
    def of(cls, normals: Sequence[LoopSummary]) -> Reference:
        if not normals:
            raise ValueError("a reference needs at least one normal run")
        return cls(max(s.op_sd for s in normals), max(s.pv_sd for s in normals),
                   normals[0].freqs, np.max([s.op_psd for s in normals], axis=0),
                   np.max([s.pv_psd for s in normals], axis=0))


@dataclasses.dataclass(frozen=True)
class OtherLabel:
    cause_class: str
    sd_ratio: float  # the larger of OP's and PV's SD over the reference's
    cycle_ratio: float  # how much more the cycle's band grew than the whole spectrum (OP, PV)


def other_label(loop: LoopSummary, ref: Reference, *, sticky: bool,
                cycles_hz: Sequence[float], disturbed: bool) -> OtherLabel:
    """Label a loop whose valve is good (module doc): ``sticky`` whether the run has a
    sticky valve, ``cycles_hz`` the stick-slip cycles its sticky valves show, ``disturbed``
    whether another disturbance is active."""
    sd = max(loop.op_sd / max(ref.op_sd, 1e-12), loop.pv_sd / max(ref.pv_sd, 1e-12))
    cyc = 0.0
    for f0 in cycles_hz:
        for own, base in ((loop.op_psd, ref.op_psd), (loop.pv_psd, ref.pv_psd)):
            grew = band_power(loop.freqs, own, f0) / max(band_power(ref.freqs, base, f0), 1e-30)
            overall = float(own.sum()) / max(float(base.sum()), 1e-30)
            cyc = max(cyc, grew / max(overall, 1.0))
    if cyc >= CYCLE_RATIO or (sticky and not disturbed and sd >= SD_RATIO):
        return OtherLabel("propagated", sd, cyc)
    if disturbed and sd >= SD_RATIO:
        return OtherLabel("disturbance", sd, cyc)
    return OtherLabel("normal", sd, cyc)
