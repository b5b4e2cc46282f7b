"""The loads and noise a shape-corpus loop carries (lab/shape/draws.py gives the ranges):
what enters at the process input (coloured noise, a random walk, steps, a real residual,
an external periodic load, a propagated stick-slip cycle), what is added to the measured PV
(white noise, a real residual) and the setpoint.

Real residuals come from ../shared/data/unlabelled-factory ONLY (two factory loops, one
week at 1 min, no label): never from the labelled plant records, the held-out test. Each
of their four signals (OP and PV of both loops) minus its running median over 4 h, robustly
standardised and clipped at 6 SD, is a library of real variation; a loop replays a random
stretch of one, time-stretched by 0.5-30 steps per minute-sample and, half the time, with
its Fourier phases randomised (the spectrum of a real plant without whatever shape the
factory loop's own valve may give it)."""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import ndimage, signal

from stiction._validate import FloatArray

from ..sources.records import SHARED
from .draws import Loop, loguniform

FACTORY = SHARED / "unlabelled-factory"


@functools.cache
def residuals() -> tuple[FloatArray, ...]:
    """The factory signals' residuals (module doc)."""
    out = []
    for name in ("FIC-211", "LIC-106"):
        data = np.genfromtxt(FACTORY / f"{name}.csv", delimiter=",", names=True,
                             dtype=None, encoding="utf-8")
        for col in ("op", "pv"):
            x = np.asarray(data[col], dtype=np.float64)
            good = np.isfinite(x)
            x = np.interp(np.arange(x.size), np.flatnonzero(good), x[good])
            r = x - ndimage.median_filter(x, size=241, mode="nearest")
            mad = float(np.median(np.abs(r - np.median(r)))) * 1.4826
            sd = mad if mad > 0 else float(np.std(r)) or 1.0
            out.append(np.clip((r - np.median(r)) / sd, -6.0, 6.0))
    return tuple(out)


def replay(rng: np.random.Generator, n: int) -> FloatArray:
    """A unit-SD stretch of a real residual, ``n`` steps long (module doc)."""
    lib = residuals()
    x = lib[int(rng.integers(0, len(lib)))]
    stretch = loguniform(rng, 0.5, 30.0)
    m = min(x.size - 2, math.ceil(n / stretch) + 2)
    start = int(rng.integers(0, x.size - m))
    seg = x[start : start + m].copy()
    if rng.random() < 0.5:
        spec = np.fft.rfft(seg - seg.mean())
        spec *= np.exp(2j * np.pi * rng.random(spec.size))
        seg = np.fft.irfft(spec, seg.size)
    t = np.arange(n) / stretch
    t = t * min(1.0, (m - 1) / max(t[-1], 1e-9))  # a long loop reuses a shorter residual
    y = np.interp(t, np.arange(m), seg)
    return np.asarray((y - y.mean()) / max(float(np.std(y)), 1e-12), dtype=np.float64)


def coloured(rng: np.random.Generator, n: int, tau: float) -> FloatArray:
    """Unit-SD white noise through a first-order filter of ``tau`` steps."""
    c = math.exp(-1.0 / max(tau, 1e-3))
    w = rng.standard_normal(n) * math.sqrt(1.0 - c * c)
    return np.asarray(signal.lfilter([1.0], [1.0, -c], w), dtype=np.float64)


def lag(x: FloatArray, tau: float) -> FloatArray:
    c = math.exp(-1.0 / max(tau, 1e-3))
    return np.asarray(signal.lfilter([1.0 - c], [1.0, -c], x), dtype=np.float64)


def periodic(rng: np.random.Generator, kind: str, period: float, n: int) -> FloatArray:
    """An external periodic load, unit amplitude: a sine, a square wave or a sawtooth
    through a lag (as a load arrives through process dynamics), or two tones."""
    ph = np.arange(n) / period + rng.uniform(0, 1)
    if kind == "sine":
        x = np.sin(2 * np.pi * ph)
    elif kind == "square":
        x = lag(np.sign(np.sin(2 * np.pi * ph)), period * rng.uniform(0.05, 0.3))
    elif kind == "sawtooth":
        saw = 2.0 * (ph % 1.0) - 1.0
        x = lag(saw if rng.random() < 0.5 else -saw, period * rng.uniform(0.01, 0.1))
    else:
        x = np.sin(2 * np.pi * ph) + 0.6 * np.sin(2 * np.pi * ph * rng.uniform(2.2, 3.7) + 1.0)
    x = np.asarray(x, dtype=np.float64)
    return x / max(float(np.max(np.abs(x))), 1e-12)


def load(loop: Loop, rng: np.random.Generator, n: int, upstream: FloatArray | None
         ) -> FloatArray:
    """Everything at the process input of ``loop`` (fraction of span), ``n`` steps.
    ``upstream`` is a sticky loop's PV elsewhere (unit SD, its period about the loop's
    drawn one), used when the loop draws a propagated cycle."""
    x = loop.load_sd * coloured(rng, n, loop.load_tau)
    if loop.walk:
        w = np.cumsum(rng.standard_normal(n))
        w = signal.detrend(w) if rng.random() < 0.5 else w - w[0]
        x += loop.walk * w / max(float(np.ptp(w)), 1e-12)
    for _ in range(loop.steps):
        x[int(rng.integers(0, n)) :] += rng.uniform(-0.02, 0.02)
    if loop.residual_load:
        x += loop.residual_load * lag(replay(rng, n), loop.scale * rng.uniform(0.0, 0.5))
    if loop.periodic:
        x += loop.periodic_amp * periodic(rng, loop.periodic, loop.periodic_period, n)
    if loop.propagated_amp and upstream is not None:
        x += loop.propagated_amp * math.sqrt(2.0) * upstream[:n]
    return x


def noise(loop: Loop, rng: np.random.Generator, n: int) -> FloatArray:
    """What is added to the measured PV (units): white noise and a real residual."""
    x = loop.noise * rng.standard_normal(n)
    if loop.residual_noise:
        x += loop.residual_noise * replay(rng, n)
    return x


def setpoint(loop: Loop, rng: np.random.Generator, n: int) -> FloatArray:
    sp = np.full(n, 50.0)
    for _ in range(loop.sp_steps):
        sp[int(rng.integers(0, n)) :] += rng.uniform(-10.0, 10.0)
    if loop.sp_ramp:
        a, b = sorted(rng.integers(0, n, 2))
        ramp = np.clip((np.arange(n) - a) / max(b - a, 1), 0.0, 1.0)
        sp += rng.uniform(-10.0, 10.0) * ramp
    return sp
