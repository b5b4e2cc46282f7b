"""The nonlinearity index of a cycle, with surrogate data (Thornhill, Cox and Paulonis 2003;
Thornhill 2005).

An oscillation born at a sticky valve is a limit cycle: its square or sawtooth shape holds
harmonics whose phases are locked to the fundamental's. As it travels through the plant,
process dynamics filter the harmonics away and the cycle grows more sinusoidal, so the
signal whose cycle is most nonlinear is the likeliest source of a plant-wide oscillation
(Thornhill 2005, IEEE Trans. Control Syst. Technol. 13(3), 434-443; Thornhill, Cox and
Paulonis 2003, Control Eng. Practice 11, 1481-1490).

The test (surrogate data, Theiler et al. 1992): a nonlinear time series is predicted
better, from its own past, than surrogates with its power spectrum and its distribution
but random phases. :func:`nonlinearity`:

1. **The cycle.** The signal is band-passed around the cycle (0.5 to 5.5 times the
   fundamental: the slow trends and the noise out, the harmonics in; a zero-phase
   Butterworth filter, :func:`.direction.band_passed`) and resampled to
   ``SAMPLES_PER_CYCLE`` samples a cycle, so the embedding spans the same part of a cycle
   whatever the sampling (10 s or 60 s of a historian).
2. **End matching.** The last whole number of cycles (at most ``MAX_CYCLES``), starting
   where the series' first and last values and slopes match best (a Fourier surrogate
   treats the record as periodic: a jump at the ends would add false harmonics).
3. **Surrogates.** ``SURROGATES`` phase-randomised Fourier surrogates (Theiler et al.
   1992): the same power spectrum, the phases random. Not IAAFT
   (Schreiber and Schmitz 1996), which also gives each surrogate the signal's values: for
   a square cycle the two values it jumps between rebuild the square, and the index of a
   jittered square wave fell from 1.3-3.6 to 0.1-0.7 (as low as a linear resonance's).
4. **Prediction error.** Each point ``HORIZON`` sample ahead predicted from the
   ``NEIGHBOURS`` nearest of its embedding vectors (``EMBED`` samples, half a cycle; the
   neighbours at least half a cycle away in time), the mean absolute error of the signal
   and of each surrogate.
5. **The index.** ``NLI = (mean of the surrogates' errors - the signal's error) / (3 x their
   standard deviation)``: above 1 the cycle is nonlinear (Thornhill's three sigma), near 0
   or below it is not told from a linear one.

The parameters are this project's starting points, set on test cycles whose answer is
known (a jittered square and sawtooth wave against a linear resonance: indices 1.3-3.5
against -0.1-0.6, tests/stiction/plant/test_evidence.py); the papers' own values differ in
detail.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._validate import FloatArray
from .direction import band_passed

__all__ = ["NLI_NONLINEAR", "Nonlinearity", "nonlinearity"]

SAMPLES_PER_CYCLE = 16
EMBED = 8  # half a cycle
HORIZON = 1
NEIGHBOURS = 4
SURROGATES = 11
MAX_CYCLES = 24
MIN_CYCLES = 5
"""Whole cycles the window must hold for an index (fewer: None): the nearest neighbours of
one cycle are found in the others."""
NLI_NONLINEAR = 1.0
"""An index above this: the cycle is nonlinear (Thornhill 2005)."""


@dataclasses.dataclass(frozen=True)
class Nonlinearity:
    """``index`` (NLI), the signal's prediction error and the surrogates' (mean and
    standard deviation), all relative to the band-passed cycle's standard deviation."""

    index: float
    error: float
    surrogate_error: float
    surrogate_sd: float
    cycles: int

    @property
    def nonlinear(self) -> bool:
        return self.index > NLI_NONLINEAR


def _band_cycles(x: FloatArray, period: float) -> FloatArray | None:
    """``x`` band-passed around its cycle of ``period`` samples, resampled to
    ``SAMPLES_PER_CYCLE`` a cycle, the last whole cycles end-matched; None when too short."""
    cycles = min(MAX_CYCLES, int(x.size / period))
    if cycles < MIN_CYCLES:
        return None
    y = band_passed(x, period)
    step = period / SAMPLES_PER_CYCLE
    grid = np.arange(0.0, x.size - 1, step)
    z = np.interp(grid, np.arange(x.size), y)
    length = cycles * SAMPLES_PER_CYCLE
    if z.size < length:
        cycles = (z.size // SAMPLES_PER_CYCLE)
        length = cycles * SAMPLES_PER_CYCLE
        if cycles < MIN_CYCLES:
            return None
    last = z.size - length
    first = max(0, last - SAMPLES_PER_CYCLE)
    starts = np.arange(first, last + 1)
    dz = np.gradient(z)
    cost = (z[starts] - z[starts + length - 1]) ** 2 + (dz[starts] - dz[starts + length - 1]) ** 2
    s = int(starts[int(np.argmin(cost))])
    seg = z[s:s + length]
    sd = float(np.std(seg))
    if not sd > 0:
        return None
    return np.asarray((seg - float(np.mean(seg))) / sd)


def _surrogates(x: FloatArray, count: int, rng: np.random.Generator) -> FloatArray:
    """``count`` phase-randomised surrogates of ``x`` (rows): its amplitude spectrum, random
    phases, unit variance."""
    amp = np.abs(np.fft.rfft(x))
    phases = rng.uniform(0.0, 2.0 * np.pi, (count, amp.size))
    phases[:, 0] = 0.0
    if x.size % 2 == 0:
        phases[:, -1] = 0.0
    out = np.fft.irfft(amp * np.exp(1j * phases), n=x.size, axis=1)
    out -= out.mean(axis=1, keepdims=True)
    return np.asarray(out / out.std(axis=1, keepdims=True))


def _prediction_errors(xs: FloatArray) -> FloatArray:
    """Per row of ``xs``: the mean absolute error of predicting it ``HORIZON`` samples ahead
    from the ``NEIGHBOURS`` nearest embedding vectors at least half a cycle away in time
    (every second point predicted: the error is a mean, half the points estimate it as
    well; all rows in one batch)."""
    n = xs.shape[1] - EMBED + 1 - HORIZON
    windows = np.lib.stride_tricks.sliding_window_view(xs.astype(np.float32), EMBED,
                                                       axis=1)[:, :n]
    targets = np.arange(0, n, 2)
    sq = np.einsum("kij,kij->ki", windows, windows)
    d = sq[:, targets, None] + sq[:, None, :] - 2.0 * np.matmul(
        windows[:, targets], windows.transpose(0, 2, 1))
    d[:, np.abs(targets[:, None] - np.arange(n)[None, :]) < SAMPLES_PER_CYCLE // 2] = np.inf
    near = np.argpartition(d, NEIGHBOURS, axis=2)[:, :, :NEIGHBOURS]
    rows = np.arange(xs.shape[0])[:, None, None]
    pred = xs[rows, near + EMBED - 1 + HORIZON].mean(axis=2)
    target = xs[:, targets + EMBED - 1 + HORIZON]
    return np.asarray(np.mean(np.abs(pred - target), axis=1))


def nonlinearity(x: FloatArray, period: float, *, seed: int = 0) -> Nonlinearity | None:
    """The nonlinearity index of ``x``'s cycle of ``period`` samples (module doc); None
    when ``x`` holds fewer than ``MIN_CYCLES`` cycles or is flat. Deterministic for
    ``seed``."""
    if not (math.isfinite(period) and period > 0):
        return None
    z = _band_cycles(np.asarray(x, dtype=np.float64), period)
    if z is None:
        return None
    rng = np.random.default_rng(seed)
    all_errors = _prediction_errors(np.vstack((z, _surrogates(z, SURROGATES, rng))))
    own, errors = float(all_errors[0]), all_errors[1:]
    mean, sd = float(errors.mean()), float(errors.std(ddof=1))
    index = (mean - own) / (3.0 * sd) if sd > 0 else 0.0
    return Nonlinearity(float(index), own, mean, sd, z.size // SAMPLES_PER_CYCLE)
