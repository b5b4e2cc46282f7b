"""Named simulation scenarios: every closed-loop case of He & Wang (2014), plus loops that
oscillate for reasons other than stiction.

``scenario(name, **overrides)`` gives a :class:`Scenario`; ``simulate(...)`` runs one and
returns its time series. Paper cases (method notes section 2, Ts = 1 s):

=============  ==============================  =================  ======================
name           process                         controller         valve (He model, K 1.99)
=============  ==============================  =================  ======================
table4-case1   1/(12s+1)                       Kc 1, Ti 6         fd 0.07, fs 0.08
table4-case2   1/(12s+1)                       Kc 1, Ti 6         fd 0.27, fs 0.30
table5-case1   exp(-s)/(5s)                    Kc 2, Ti 90        fd 0.07, fs 0.08
table5-case2   exp(-s)/(5s)                    Kc 2, Ti 90        fd 0.27, fs 0.30
table6         exp(-6s)/(tau·s+1), ``tau``     Kc 2, Ti 120       fd 0.18, fs 0.20
table7         exp(-theta·s)/(120s+1), theta   Kc 2, Ti 120       fd 0.18, fs 0.20
table9         exp(-6s)/(120s+1) (nominal)     Kc 2, Ti 120       fd 0.18, fs 0.20
=============  ==============================  =================  ======================

Non-stiction oscillations (perfect valve, fs = fd = 0, K = 1):
``healthy`` (the table9 loop, settles), ``aggressive-tuning`` (exp(-10s)/(60s+1) with Kc at
95 % of its ultimate gain, excited by a random load, so it rings at its resonance) and
``disturbance`` (the table9 loop with a sinusoidal load of 5 % span, period 600 s).

Each loop starts at rest at its operating point (OP = VP = 50 %) and gets a setpoint step
of ``sp_step`` PV units at ``sp_step_time`` s, which starts the stiction limit cycle.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .. import _validate as v
from .._errors import ParameterError
from .._validate import FloatArray
from ..models.simulate import LoopBank, LoopParams
from ..models.valves import HeValve

__all__ = ["SCENARIOS", "Scenario", "SimResult", "scenario", "simulate"]


@dataclasses.dataclass(frozen=True)
class Scenario:
    """One closed loop with a He-model valve, in the paper's terms (all scalars)."""

    name: str
    description: str
    fs: float = 0.0
    fd: float = 0.0
    k: float = 1.99
    kc: float = 2.0
    ti: float = 120.0
    kp: float = 1.0
    tau: float = 120.0
    theta: float = 6.0
    integrating: bool = False
    ts: float = 1.0
    sp_step: float = 2.0
    sp_step_time: float = 20.0
    dist_amp: float = 0.0
    dist_period: float = 0.0
    load_sd: float = 0.0
    load_tau: float = 30.0
    duration: float = 3600.0

    def __post_init__(self) -> None:
        v.non_negative("fs", self.fs)
        v.non_negative("fd", self.fd)
        if self.fd > self.fs:
            raise ParameterError("fd", f"must not exceed fs (fd={self.fd}, fs={self.fs})")
        v.positive_scalar("ts", self.ts)
        v.positive_scalar("ti", self.ti)
        v.positive_scalar("duration", self.duration)
        v.non_negative("theta", self.theta)
        if not self.integrating:
            v.positive_scalar("tau", self.tau)

    @property
    def sticky(self) -> bool:
        return self.fs > 0

    def valve(self) -> HeValve:
        return HeValve(self.fs, self.fd, self.k)

    def loop_params(self, noise: float = 0.0) -> LoopParams:
        return LoopParams(
            kc=self.kc, ti=self.ti, kp=self.kp, tau=self.tau, theta=self.theta,
            integrating=self.integrating, noise_sd=noise, dist_amp=self.dist_amp,
            dist_period=self.dist_period, load_sd=self.load_sd, load_tau=self.load_tau,
        )


_PERFECT: dict[str, Any] = {"fs": 0.0, "fd": 0.0, "k": 1.0}
# The Table 6-9 loop cycles slowly (period about 2200 s at tau = 120): 4 h hold 6 cycles.
_TABLE6_LOOP: dict[str, Any] = {
    "kc": 2.0, "ti": 120.0, "tau": 120.0, "theta": 6.0, "fd": 0.18, "fs": 0.20, "duration": 14400.0,
}

SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in [
        Scenario("table4-case1", "Table 4 flow loop, mild stiction", fd=0.07, fs=0.08,
                 kc=1.0, ti=6.0, tau=12.0, theta=0.0, duration=1200.0),
        Scenario("table4-case2", "Table 4 flow loop, severe stiction", fd=0.27, fs=0.30,
                 kc=1.0, ti=6.0, tau=12.0, theta=0.0, duration=1200.0),
        Scenario("table5-case1", "Table 5 level loop, mild stiction", fd=0.07, fs=0.08,
                 kc=2.0, ti=90.0, kp=0.2, theta=1.0, integrating=True, duration=4000.0),
        Scenario("table5-case2", "Table 5 level loop, severe stiction", fd=0.27, fs=0.30,
                 kc=2.0, ti=90.0, kp=0.2, theta=1.0, integrating=True, duration=4000.0),
        Scenario("table6", "Table 6 loop, time constant --tau (90..480)", **_TABLE6_LOOP),
        Scenario("table7", "Table 7 loop, dead time --theta (5..35)",
                 **{**_TABLE6_LOOP, "theta": 5.0}),
        Scenario("table9", "Table 9 nominal loop exp(-6s)/(120s+1)", **_TABLE6_LOOP),
        Scenario("healthy", "Table 9 loop with a perfect valve: settles",
                 **{**_TABLE6_LOOP, **_PERFECT}),
        Scenario("aggressive-tuning", "Perfect valve, Kc at 95 % of ultimate gain, random load",
                 kc=8.5, ti=60.0, tau=60.0, theta=10.0, load_sd=0.01, load_tau=30.0, **_PERFECT),
        Scenario("disturbance", "Perfect valve, sinusoidal load 5 % span, period 600 s",
                 dist_amp=0.05, dist_period=600.0, **{**_TABLE6_LOOP, **_PERFECT}),
    ]
}


def scenario(name: str, **overrides: Any) -> Scenario:
    """The named scenario with parameters replaced by ``overrides`` (validated)."""
    try:
        base = SCENARIOS[name]
    except KeyError:
        known = ", ".join(SCENARIOS)
        raise ParameterError("scenario", f"is unknown: {name!r} (known: {known})") from None
    fields = {f.name for f in dataclasses.fields(Scenario)} - {"name", "description"}
    for key in overrides:
        if key not in fields:
            raise ParameterError(key, f"is not a scenario parameter (known: {sorted(fields)})")
    return dataclasses.replace(base, **overrides)


@dataclasses.dataclass(frozen=True)
class SimResult:
    """Time series of one simulated loop: OP, VP in % of span; PV, SP in PV units."""

    t: FloatArray
    sp: FloatArray
    op: FloatArray
    pv: FloatArray
    vp: FloatArray
    scenario: Scenario


def simulate(
    sc: Scenario | str,
    *,
    duration: float | None = None,
    noise: float = 0.0,
    seed: int | None = 0,
) -> SimResult:
    """Run one scenario for ``duration`` s (default: the scenario's own) with white
    measurement noise of standard deviation ``noise`` (PV units)."""
    if isinstance(sc, str):
        sc = scenario(sc)
    dur = sc.duration if duration is None else v.positive_scalar("duration", duration)
    v.non_negative("noise", noise)
    n = round(dur / sc.ts)
    bank = LoopBank(1, sc.loop_params(noise), sc.valve(), ts=sc.ts, seed=seed)
    out = np.empty((5, n))
    for i in range(n):
        t = i * sc.ts
        sp = 50.0 + (sc.sp_step if t >= sc.sp_step_time else 0.0)
        step = bank.step(sp)
        out[:, i] = (t, step.sp[0], step.op[0], step.pv[0], step.vp[0])
    return SimResult(*out, scenario=sc)  # type: ignore[misc]
