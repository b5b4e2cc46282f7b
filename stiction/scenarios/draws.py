"""What one realistic record is drawn from: its process, tuning, valve, loads, setpoints,
sampling and units (see :mod:`.realistic`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from .._validate import FloatArray

__all__ = ["CAUSES", "Draw", "draw", "filtered_noise", "load_signal", "loguniform",
           "periodic_load", "setpoint_steps"]

CAUSES = ("stiction", "tuning", "disturbance", "propagated", "noise", "ramp-load")
"""What makes a realistic loop behave as it does (see :mod:`.realistic`)."""


MAX_SAMPLES = 10_000


OVERSAMPLE = 4  # simulation steps per historian sample


SAMPLE_TIMES = (1.0, 1.0, 2.0, 5.0, 10.0, 10.0, 30.0, 60.0)


OP_UNITS: tuple[tuple[float, float, str], ...] = (
    (1.0, 0.0, "% of span"),
    (1.0, 0.0, "% of span"),
    (0.01, 0.0, "0-1"),
    (0.16, 4.0, "mA"),
    (163.83, 0.0, "counts 0-16383"),
    (-1.0, 100.0, "% reverse acting"),
    (2.5, 300.0, "engineering units with offset"),
    (1.0, -50.0, "% with offset -50"),
)


WAVEFORMS = ("sine", "square", "two-tone")


RAMP_WAVEFORMS = ("triangle", "sawtooth")


@dataclasses.dataclass
class Draw:
    """Everything drawn for one record before simulation (fractions of span, seconds)."""

    cause: str
    index: int
    rng: np.random.Generator
    ts: float
    n: int
    integrating: bool
    kp: float
    tau: float
    theta: float
    kc: float = 0.0
    ti: float = 0.0
    x0: float = 0.5
    noise: float = 0.1
    valve: str = "perfect"
    s: float = 0.0
    j: float = 0.0
    notes: list[str] = dataclasses.field(default_factory=list)

    @property
    def ts_sim(self) -> float:
        return self.ts / OVERSAMPLE

    @property
    def n_sim(self) -> int:
        """Simulation steps: a sticky loop runs long enough for the longest record, which
        is cut to hold ``MIN_CYCLES`` of its cycle once the cycle is known."""
        n = MAX_SAMPLES if self.cause == "stiction" else self.n
        return OVERSAMPLE * (n + self.warm)

    @property
    def warm(self) -> int:
        return 500


def loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _ultimate_gain(d: Draw) -> float:
    """Gain at which the PI loop (integral time ``d.ti``) reaches -180 degrees of phase:
    the process with its dead time plus 1.5 simulation steps (hold and computation)."""
    theta = d.theta + 1.5 * d.ts_sim
    w = np.geomspace(1e-6, math.pi / d.ts_sim, 4000)
    pi_phase = -np.arctan(1.0 / (d.ti * w))
    if d.integrating:
        phase = -math.pi / 2 - theta * w + pi_phase
        mag = d.kp / w
    else:
        phase = -theta * w - np.arctan(d.tau * w) + pi_phase
        mag = d.kp / np.sqrt(1.0 + (d.tau * w) ** 2)
    mag = mag * np.sqrt(1.0 + 1.0 / (d.ti * w) ** 2)
    k = np.flatnonzero(phase <= -math.pi)
    if k.size == 0:
        return float("inf")
    return float(1.0 / mag[k[0]])


def draw(cause: str, index: int, seed: int) -> Draw:
    rng = np.random.default_rng((seed, CAUSES.index(cause), index))
    ts = float(rng.choice(SAMPLE_TIMES))
    n = int(loguniform(rng, 300, 10_000))
    integrating = bool(rng.random() < 0.3)
    # dynamics in historian samples: from a few to about a hundred
    if integrating:
        horizon = ts * loguniform(rng, 4.0, 60.0)  # closed-loop time scale
        kp, tau, theta = 1.0 / horizon, 1.0, horizon * rng.uniform(0.0, 0.2)
    else:
        tau = ts * loguniform(rng, 1.5, 60.0)
        kp, theta = loguniform(rng, 0.3, 3.0), tau * rng.uniform(0.0, 0.5)
    d = Draw(cause, index, rng, ts, n, integrating, kp, tau, theta)
    # SIMC tuning (Skogestad 2003), with lambda drawn between tight and relaxed
    if integrating:
        lam = horizon * rng.uniform(0.3, 1.0)
        d.kc, d.ti = 1.0 / (kp * (lam + theta + d.ts_sim)), 4.0 * (lam + theta + d.ts_sim)
    else:
        lam = max(theta, tau * rng.uniform(0.2, 1.0))
        d.kc = tau / (kp * (lam + theta + d.ts_sim))
        d.ti = min(tau, 4.0 * (lam + theta + d.ts_sim))
    d.x0 = rng.uniform(0.25, 0.75)
    d.noise = loguniform(rng, 0.02, 0.5)
    if cause == "tuning":
        if rng.random() < 0.7:
            d.kc = _ultimate_gain(d) * rng.uniform(0.6, 0.9)
            d.notes.append("gain at 60-90 % of ultimate")
        else:
            d.ti = d.ti * rng.uniform(0.03, 0.12)
            d.kc = min(d.kc, 0.9 * _ultimate_gain(d))
            d.notes.append("integral time far too short")
        if not math.isfinite(d.kc):
            d.kc = 10.0 / kp
    elif cause == "stiction":
        d.valve = str(rng.choice(("he", "he", "choudhury", "kano")))
        fs = loguniform(rng, 0.01, 0.08)
        fd = fs * rng.uniform(0.4, 0.9)
        d.s, d.j = fs + fd, fs - fd  # He (fs, fd) -> band S and slip J
        # PV noise through the controller gain moves OP by at most a third of fs
        d.noise = min(d.noise, rng.uniform(0.05, 0.3) * fs * 100.0 / d.kc)
        d.notes.append(f"{d.valve} valve fs {fs:.3f} fd {fd:.3f}")
    return d


def filtered_noise(rng: np.random.Generator, n: int, tau_samples: float) -> FloatArray:
    """Unit-SD white noise through a first-order filter of ``tau_samples``."""
    c = math.exp(-1.0 / max(tau_samples, 1e-3))
    w = rng.standard_normal(n) * math.sqrt(1.0 - c * c)
    return np.asarray(signal.lfilter([1.0], [1.0, -c], w), dtype=np.float64)


def load_signal(d: Draw) -> FloatArray:
    """Load at the process input, fraction of span, one value per simulation step: coloured
    noise, a bounded random walk and steps, each of a few percent of span. A sticky valve's
    loop gets them scaled to its static friction instead (coloured SD 5-30 % of fs, walk
    and steps up to 1.5 fs): a loop whose loads swamp the stiction shows no stiction
    pattern to label it by, and is not what a plant engineer calls a sticky valve."""
    rng, n = d.rng, d.n_sim
    cl = (d.ti if not d.integrating else d.ti / 2.0) / d.ts_sim  # closed-loop scale, steps
    sticky = d.cause == "stiction"
    unit = 0.5 * (d.s + d.j) if sticky else 0.01
    sd = unit * (rng.uniform(0.05, 0.3) if sticky else rng.uniform(0.1, 1.5))
    load = sd * filtered_noise(rng, n, cl * loguniform(rng, 0.3, 10.0))
    walk = np.cumsum(rng.standard_normal(n))
    walk = signal.detrend(walk) if rng.random() < 0.5 else walk - walk[0]
    big = 1.5 if sticky else 3.0
    load += unit * rng.uniform(0.0, big) * walk / max(float(np.ptp(walk)), 1e-12)
    for _ in range(rng.poisson(0.7)):
        load[rng.integers(0, n) :] += unit * rng.uniform(-big, big)
    return load


def periodic_load(d: Draw, kind: str) -> FloatArray:
    rng, n = d.rng, d.n_sim
    period = d.ts * loguniform(rng, 8.0, 150.0) / d.ts_sim  # steps
    ph = np.arange(n) / period + rng.uniform(0, 1)
    frac = ph % 1.0
    if kind == "sine":
        x = np.sin(2 * np.pi * ph)
    elif kind == "square":
        c = math.exp(-1.0 / (period * rng.uniform(0.05, 0.3)))
        x = signal.lfilter([1.0 - c], [1.0, -c], np.sign(np.sin(2 * np.pi * ph)))
    elif kind == "triangle":
        x = 4.0 * np.abs(frac - 0.5) - 1.0
    elif kind == "sawtooth":
        x = 2.0 * frac - 1.0
    else:
        x = np.sin(2 * np.pi * ph) + 0.6 * np.sin(2 * np.pi * ph * rng.uniform(2.2, 3.7) + 1.0)
    x = np.asarray(x, dtype=np.float64)
    return 0.01 * rng.uniform(1.0, 5.0) * x / max(float(np.std(x)) * math.sqrt(2.0), 1e-12)


def setpoint_steps(d: Draw) -> FloatArray:
    sp = np.zeros(d.n_sim)
    if d.rng.random() < 0.5:
        for _ in range(int(d.rng.integers(1, 4))):
            sp[d.rng.integers(0, d.n_sim) :] += d.rng.uniform(-5.0, 5.0)
    return sp
