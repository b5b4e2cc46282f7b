"""What the fit's statistics say: +1 a sticky valve explains PV, -1 a linear one does, 0."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..._validate import FloatArray
from ...signal.arrays import median

__all__ = ["EXPLAINED_NO", "EXPLAINED_NO_PROCESS", "EXPLAINED_YES", "GAIN_YES", "IMPROVE_NO",
           "IMPROVE_YES", "SPREAD_YES", "Stats", "decide", "swing_at_onsets"]


# the thresholds (the package doc says where each comes from)
EXPLAINED_YES = 0.5


IMPROVE_YES = 0.2


SPREAD_YES = 0.15


GAIN_YES = 0.02  # of PV's variance: the share the sticky valve explains beyond the linear one


EXPLAINED_NO = 0.6


EXPLAINED_NO_PROCESS = 0.4


IMPROVE_NO = 0.1


@dataclasses.dataclass(frozen=True)
class Stats:
    """What the vote reads (see the module doc)."""

    explained: float  # share of PV the process path's sticky valve explains
    level: float  # its improvement over either linear valve, in levels
    increments: float  # ... in increments, over the process path's linear valve
    gain: float  # share of PV's variance it explains beyond the linear valve (levels)
    spread: float  # ... without the period where it gains most (process paths, both)
    delta_aic: float
    sigma: float  # the controller's sign, 0 unknown
    explained_linear: float  # share of PV the best linear valve (any path) explains
    explained_process: float  # ... the linear valve through the process path
    level_process: float  # the process path's sticky valve over its linear one, levels


def swing_at_onsets(u: FloatArray, vp: FloatArray, lag: int) -> float | None:
    """Median OP swing between consecutive valve moves of opposite direction, OP read at
    each move's centre (weighted by the movement) shifted by the fitted dead time, that is at
    PV's onsets: He & Wang's eq 9 read at the fitted jumps, without a delay shift. A move is
    a run of samples in which the fitted valve goes one way (a jump, and the following of OP
    that the fit may add to it). None when fewer than two swings."""
    dv = vp[1:] - vp[:-1]
    adv = np.abs(dv)
    idx = (adv > 1e-9 * float(np.maximum.reduce(adv, initial=0.0))).nonzero()[0]
    if idx.size < 3:
        return None
    sign = np.sign(dv[idx])
    new = np.concatenate(([True], (idx[1:] - idx[:-1] > 1) | (sign[1:] != sign[:-1])))
    run = new.cumsum() - 1
    w = np.abs(dv[idx])
    centre = np.bincount(run, w * idx) / np.bincount(run, w)
    onset = np.rint(centre).astype(np.intp) + 1 + lag
    run_sign = sign[new]
    ok = onset < u.size
    onset, run_sign = onset[ok], run_sign[ok]
    alt = run_sign[1:] != run_sign[:-1]
    at = u[onset]
    swings = np.abs(at[1:] - at[:-1])[alt]
    return median(swings) if swings.size >= 2 else None


def decide(st: Stats, fd: float) -> tuple[int, str]:
    if (st.sigma != 0 and st.explained >= EXPLAINED_YES and st.level >= IMPROVE_YES
            and st.gain >= GAIN_YES and st.increments >= IMPROVE_YES
            and st.spread >= SPREAD_YES):
        return 1, (f"a sticky valve (fd {fd:.3g} OP units) explains {st.explained:.0%} of PV, "
                   f"a linear one {max(st.explained_linear, 0.0):.0%}; better in levels "
                   f"({st.level:.0%}) and in increments ({st.increments:.0%}), cycle after "
                   "cycle")
    if (st.explained_linear >= EXPLAINED_NO and st.explained_process >= EXPLAINED_NO_PROCESS
            and st.increments <= IMPROVE_NO and st.level_process < IMPROVE_YES):
        return -1, (f"a linear valve explains {st.explained_linear:.0%} of PV "
                    f"({st.explained_process:.0%} through the process); a sticky one adds "
                    "nothing")
    why = ("the controller's sign is unclear" if st.sigma == 0 else
           f"better in levels by {max(st.level, -9.99):.0%}, in increments by "
           f"{max(st.increments, -9.99):.0%}, without its best cycle by "
           f"{max(st.spread, -9.99):.0%}")
    return 0, (f"sticky valve {max(st.explained, 0.0):.0%} of PV explained, linear "
               f"{max(st.explained_linear, 0.0):.0%}: not decisive ({why})")
