"""What one loop of the shape corpus is drawn from (domain randomisation, Tobin et al. 2017):
its process, tuning, valve, loads, noise, setpoints and historian. Times are in simulation
steps (1 s nominal: only ratios matter to the network), amounts in fractions of the valve's
span (loads, friction) or in PV units (PV = 50 + 100 y: 1 % of span through a unit gain is 1
unit). Every draw comes from ``numpy.random.default_rng((SEED_BASE, seed, index))``.

The ranges (lab/shape/README.md says why):

- **process**: self-regulating (70 %), tau 2-600 steps, gain 0.3-3, dead time 0-60 % of tau;
  integrating (30 %), closed-loop horizon 20-2000 steps, dead time 0-20 % of it; zero to two
  more lags of 5-50 % of tau (second and third order);
- **tuning** (SIMC, Skogestad 2003, on the first-order-plus-dead-time equivalent, then):
  ``normal`` (kc times 0.6-1.6, ti times 0.6-4), ``sluggish`` (kc times 0.1-0.5, ti times
  1-5: slow integral action gives the slow stick-slip cycles of real flow loops),
  ``aggressive`` (kc at 55-90 % of the ultimate gain: tuning-driven cycles),
  ``short-ti`` (ti 3-15 % of its SIMC value); kc never above 90 % of the ultimate gain;
- **valve**: He 2007 (K = 1), He and Wang 2014 (K 1-2), Choudhury 2005, Kano 2004, or the
  physical one (K from mass, spring and viscous friction, and a positioner lag of 1-5
  steps); static friction fs 0.1-10 % of span, log-uniform (barely visible to large),
  fd 0-95 % of fs;
- **loads** at the process input: coloured noise (SD 0.02-3 %, time constant 0.2-10 x the
  loop's), a bounded random walk, steps; a real residual replayed (half the loops, from
  ../shared/data/unlabelled-factory only); an external periodic load (25 %: sine, square
  or sawtooth through a lag, two tones; 0.2-5 %); a propagated stick-slip cycle (10 %: the
  PV of a sticky loop elsewhere through a lag of 5-100 % of its period);
- **measurement noise**: white, SD 0.01-1.5 units, or a real residual;
- **setpoint**: steps in 40 % of loops, a ramp in 10 %;
- **historian**: sampling every 1-60 steps, snapshot or the interval's mean (40 %); PV
  quantised (30 %), OP quantised (20 %); compression (40 %: deadband or swinging door,
  0.1-3 % of the signal's range), replayed by linear interpolation; 300-2,048 samples.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

SEED_BASE = 36
STEPS = 24_000  # simulated steps kept per loop (the window is cut from them)
WARM = 3_000  # steps simulated before that
VALVES = ("he", "he-k", "choudhury", "kano", "physical")
TUNINGS = ("normal", "normal", "normal", "sluggish", "sluggish", "aggressive", "short-ti")
PERIODIC = ("sine", "square", "sawtooth", "two-tone")
INTERVALS = (1, 2, 5, 10, 10, 15, 30, 60)


def loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


@dataclasses.dataclass
class Loop:
    """One loop's draw (module doc): the sticky run and its twin share all of it but the
    valve's friction."""

    seed: int
    index: int
    integrating: bool
    kp: float
    tau: float
    theta: float
    lags: tuple[float, float]
    tuning: str
    kc: float
    ti: float
    valve: str
    fs: float
    fd: float
    k: float
    x0: float
    load_sd: float
    load_tau: float
    walk: float
    steps: int
    residual_load: float  # SD of a replayed real residual at the process input, 0: none
    residual_noise: float  # SD of a replayed real residual on PV, 0: none
    noise: float  # SD of white PV noise, units
    periodic: str  # "" or the kind
    periodic_amp: float
    periodic_period: float
    propagated_amp: float  # 0: none
    sp_steps: int
    sp_ramp: bool
    interval: int
    averaged: bool
    pv_levels: float  # quantisation levels over PV's 5-95 % range, 0: none
    op_quantum: float  # fraction of span, 0: none
    compression: str  # "", "deadband", "swinging-door"
    compression_dev: float  # fraction of the signal's 5-95 % range
    samples: int
    offset: float  # where the window starts, fraction of the free room

    @property
    def scale(self) -> float:
        """The loop's time scale in steps (closed-loop speed)."""
        return self.ti if not self.integrating else self.ti / 2.0

    def describe(self) -> str:
        proc = (f"integrating kp {self.kp:.3g}" if self.integrating
                else f"tau {self.tau:.0f} kp {self.kp:.2f}")
        extra = [self.periodic and f"{self.periodic} load {self.periodic_amp:.3f}",
                 self.propagated_amp and f"propagated {self.propagated_amp:.3f}",
                 self.residual_load and "real residual load",
                 self.residual_noise and "real residual noise",
                 self.compression, self.averaged and "averaged"]
        return (f"{proc}, theta {self.theta:.0f}, lags {self.lags[0]:.0f}/{self.lags[1]:.0f}, "
                f"{self.tuning} kc {self.kc:.2f} ti {self.ti:.0f}; {self.valve} fs "
                f"{100 * self.fs:.2f} % fd {100 * self.fd:.2f} %; every {self.interval}, "
                f"{self.samples} samples; " + ", ".join(str(e) for e in extra if e))


def frequency_response(loop: Loop, w: np.ndarray) -> np.ndarray:
    """The process with its lags, dead time and 1.5 steps of hold and computation."""
    theta = loop.theta + 1.5
    g: np.ndarray = loop.kp * np.exp(-1j * w * theta)
    g = g / (1j * w) if loop.integrating else g / (1.0 + 1j * w * loop.tau)
    for lag in loop.lags:
        g = g / (1.0 + 1j * w * lag)
    return np.asarray(g)


def ultimate_gain(loop: Loop, ti: float) -> float:
    """The gain at which the PI loop (integral time ``ti``) reaches -180 degrees."""
    w = np.geomspace(1e-7, math.pi, 6000)
    c = 1.0 + 1.0 / (1j * w * ti)
    phase = np.unwrap(np.angle(frequency_response(loop, w) * c))
    k = np.flatnonzero(phase <= -math.pi)
    if k.size == 0:
        return float("inf")
    return float(1.0 / abs(frequency_response(loop, w[k[:1]])[0] * c[k[0]]))


def _tune(loop: Loop, rng: np.random.Generator) -> None:
    lagsum = sum(loop.lags)
    theta = loop.theta + lagsum + 1.5
    if loop.integrating:
        lam = (1.0 / loop.kp) * rng.uniform(0.3, 1.0)
        kc, ti = 1.0 / (loop.kp * (lam + theta)), 4.0 * (lam + theta)
    else:
        lam = max(theta, loop.tau * rng.uniform(0.2, 1.0))
        kc = loop.tau / (loop.kp * (lam + theta))
        ti = min(loop.tau, 4.0 * (lam + theta))
    if loop.tuning == "normal":
        kc, ti = kc * loguniform(rng, 0.6, 1.6), ti * loguniform(rng, 0.6, 4.0)
    elif loop.tuning == "sluggish":
        kc, ti = kc * loguniform(rng, 0.1, 0.5), ti * loguniform(rng, 1.0, 5.0)
    elif loop.tuning == "short-ti":
        ti = ti * loguniform(rng, 0.03, 0.15)
    ku = ultimate_gain(loop, ti)
    if loop.tuning == "aggressive" and math.isfinite(ku):
        kc = ku * rng.uniform(0.55, 0.9)
    loop.kc, loop.ti = min(kc, 0.9 * ku), ti


def draw(seed: int, index: int) -> Loop:
    rng = np.random.default_rng((SEED_BASE, seed, index))
    integrating = bool(rng.random() < 0.3)
    if integrating:
        horizon = loguniform(rng, 20.0, 2000.0)
        kp, tau, theta = 1.0 / horizon, horizon, horizon * rng.uniform(0.0, 0.2)
    else:
        tau = loguniform(rng, 2.0, 600.0)
        kp, theta = loguniform(rng, 0.3, 3.0), tau * rng.uniform(0.0, 0.6)
    n_lags = int(rng.choice(3, p=(0.5, 0.35, 0.15)))
    lags = [tau * loguniform(rng, 0.05, 0.5) for _ in range(n_lags)] + [0.0, 0.0]
    valve = str(rng.choice(VALVES))
    fs = loguniform(rng, 0.001, 0.1)
    k = 1.0 if valve in ("he", "choudhury", "kano") else rng.uniform(1.0, 2.0)
    if valve == "physical":  # the positioner: a first lag of 1-5 steps before the process's
        lags = [rng.uniform(1.0, 5.0), *lags]
    loop = Loop(
        seed, index, integrating, kp, tau, theta, (float(lags[0]), float(lags[1])),
        str(rng.choice(TUNINGS)), 0.0, 0.0, valve, fs, fs * rng.uniform(0.0, 0.95), k,
        rng.uniform(0.15, 0.85), 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0.0, "", 0.0, 0.0, 0.0, 0,
        False, int(rng.choice(INTERVALS)), bool(rng.random() < 0.4), 0.0, 0.0, "", 0.0,
        0, rng.random())
    _tune(loop, rng)
    loop.load_sd = loguniform(rng, 0.0002, 0.03)
    loop.load_tau = loop.scale * loguniform(rng, 0.2, 10.0)
    loop.walk = loguniform(rng, 0.0005, 0.03) if rng.random() < 0.5 else 0.0
    loop.steps = int(rng.poisson(0.7))
    loop.residual_load = loguniform(rng, 0.0005, 0.02) if rng.random() < 0.5 else 0.0
    loop.residual_noise = loguniform(rng, 0.01, 1.0) if rng.random() < 0.25 else 0.0
    loop.noise = loguniform(rng, 0.01, 1.5)
    if rng.random() < 0.25:
        loop.periodic = str(rng.choice(PERIODIC))
        loop.periodic_amp = loguniform(rng, 0.002, 0.05)
        loop.periodic_period = loop.scale * loguniform(rng, 0.5, 20.0)
    if rng.random() < 0.1:
        loop.propagated_amp = loguniform(rng, 0.002, 0.05)
    loop.sp_steps = int(rng.integers(1, 5)) if rng.random() < 0.4 else 0
    loop.sp_ramp = bool(rng.random() < 0.1)
    loop.pv_levels = loguniform(rng, 15.0, 300.0) if rng.random() < 0.3 else 0.0
    loop.op_quantum = float(rng.choice((0.001, 1 / 4095))) if rng.random() < 0.2 else 0.0
    if rng.random() < 0.4:
        loop.compression = str(rng.choice(("deadband", "swinging-door")))
        loop.compression_dev = loguniform(rng, 0.001, 0.03)
    loop.samples = min(int(loguniform(rng, 300.0, 2048.0)), STEPS // loop.interval)
    return loop
