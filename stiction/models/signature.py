"""Valve signature (He & Wang 2014, section 2.3 and Figure 2).

Air pressure cycled 0 -> 12 psi -> 0 ... at 0.02 psi/s, zero-order hold, Ts = 1 s, through
the Kayihan-Doyle physical valve and the semiphysical model normalised by Table 2 (fs, fd
from the friction forces, K from eq 5). Both positions are returned as fractions of travel.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import _validate as v
from .._validate import FloatArray
from .valves import PSI, HeValve, PhysicalParams, PhysicalValve

__all__ = ["Signature", "pressure_ramp", "valve_signature"]


def pressure_ramp(
    top_psi: float = 12.0, rate_psi_s: float = 0.02, cycles: float = 1.5, ts: float = 1.0
) -> FloatArray:
    """Triangle wave 0 -> top -> 0 ... in psi, sampled (ZOH) every ``ts`` s."""
    top = v.positive_scalar("top_psi", top_psi)
    rate = v.positive_scalar("rate_psi_s", rate_psi_s)
    cyc = v.positive_scalar("cycles", cycles)
    step = v.positive_scalar("ts", ts)
    period = 2.0 * top / rate
    t = np.arange(0.0, cyc * period + step / 2, step)
    phase = np.mod(t, period)
    out: FloatArray = np.where(phase <= period / 2, rate * phase, 2 * top - rate * phase)
    return out


@dataclasses.dataclass(frozen=True)
class Signature:
    pressure_psi: FloatArray
    u: FloatArray  # input, fraction of the span pressure
    x_physical: FloatArray  # position / travel
    x_semiphysical: FloatArray
    fs: float
    fd: float
    k: float

    @property
    def max_abs_difference(self) -> float:
        return float(np.max(np.abs(self.x_physical - self.x_semiphysical)))


def valve_signature(
    params: PhysicalParams | None = None, pressure_psi: FloatArray | None = None
) -> Signature:
    """Run ``pressure_psi`` (default :func:`pressure_ramp`) through both models."""
    p = params or PhysicalParams()
    psi = pressure_ramp() if pressure_psi is None else np.asarray(pressure_psi, dtype=float)
    fs, fd, k = p.normalised()
    phys = PhysicalValve(p)
    semi = HeValve(fs, fd, k)
    pa = psi * PSI
    u = pa / p.pressure_span
    ps = phys.initial_state(pa[0])
    ss = semi.initial_state(u[0])
    xp = np.empty(len(psi))
    xs = np.empty(len(psi))
    for i in range(len(psi)):
        ps = phys.step(ps, pa[i])
        ss = semi.step(ss, u[i])
        xp[i] = float(ps.x) / p.xm
        xs[i] = float(ss.x)
    return Signature(psi, u, xp, xs, fs, fd, k)
