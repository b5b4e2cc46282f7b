"""Closed loops with a sticky valve whose position is read (stiction's own simulator:
:class:`stiction.models.simulate.LoopBank` with the He, Choudhury and Kano valve models),
for the tests of the travel measurement (``stiction.quantify.travel``)."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from stiction.models.simulate import LoopBank, LoopParams

WARM = 500  # samples dropped while the limit cycle starts


class Run(NamedTuple):
    op: np.ndarray  # % of span
    pv: np.ndarray
    position: np.ndarray  # % of span, as a positioner reports it (with its noise)


def run_loops(valve: Any, n: int, *, samples: int = 4000, pv_noise: float = 0.0,
              position_noise: float = 0.0, seed: int = 0, sp_step: float = 2.7,
              **params: Any) -> list[Run]:
    """``n`` loops (``valve``'s parameters broadcast to them) after a setpoint step of
    ``sp_step``: a FOPTD 1/(30 s + 1) e^-3s under PI (Kc 1, Ti 30 s) unless ``params`` say
    otherwise; Ts 1 s."""
    base: dict[str, Any] = {"kc": 1.0, "ti": 30.0, "tau": 30.0, "theta": 3.0}
    bank = LoopBank(n, LoopParams(**{**base, **params, "noise_sd": pv_noise}), valve,
                    ts=1.0, seed=seed)
    out = np.empty((3, n, samples))
    for i in range(samples):
        s = bank.step(50.0 + (sp_step if i > 20 else 0.0))
        out[:, :, i] = s.op, s.pv, s.vp
    rng = np.random.default_rng(seed + 1)
    pos = out[2] + rng.normal(0.0, position_noise, out[2].shape) if position_noise else out[2]
    return [Run(out[0, k, WARM:], out[1, k, WARM:], pos[k, WARM:]) for k in range(n)]
