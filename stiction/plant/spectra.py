"""Every signal's power spectrum on one frequency grid, and what a band of it holds.

Each signal (a loop's OP or PV, or an indicator) is cleaned the way the per-loop analysis
sees it (gaps filled, mean and straight line removed), tapered with a Hann window and
transformed; all signals of one length in one FFT. The spectrum is normalised to unit
power from ``MIN_CYCLES`` cycles a window up to Nyquist (a cycle's harmonics count), so
spectra of signals in other units compare. Band sums come from cumulative sums: the power
of any band of any signal costs two look-ups.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._validate import FloatArray
from ..signal.oscillation import detrend

__all__ = ["MIN_CYCLES", "MIN_PERIOD", "Spectra", "spectra"]

MIN_PERIOD = 2.5
"""Samples: the fastest cycle a group can have (its fundamental must be resolved: its band,
12 % either side, below Nyquist). A historian's 60 s export of a 2.5-3 minute cycle is 2.6-3
samples a period: with 4 here it formed no group at all (issue 37)."""
MIN_CYCLES = 3.0
"""Cycles the window must hold for a period to count."""


@dataclasses.dataclass(frozen=True)
class Spectra:
    """``power[i]``: signal ``i``'s spectrum over ``freqs`` (cycles per sample), unit sum
    over the analysed range; ``usable[i]`` False for a signal that is constant or mostly
    missing (its row is zero)."""

    freqs: FloatArray
    power: FloatArray
    usable: np.ndarray
    n: int  # samples per signal
    _cum: FloatArray = dataclasses.field(repr=False)

    def band(self, lo: float, hi: float) -> FloatArray:
        """Every signal's power between ``lo`` and ``hi`` cycles per sample."""
        i = int(np.searchsorted(self.freqs, lo, side="left"))
        j = int(np.searchsorted(self.freqs, hi, side="right"))
        return np.asarray(self._cum[:, j] - self._cum[:, i])

    def band_of(self, rows: np.ndarray, lo: float, hi: float) -> FloatArray:
        """The power between ``lo`` and ``hi`` of the signals ``rows`` only."""
        i = int(np.searchsorted(self.freqs, lo, side="left"))
        j = int(np.searchsorted(self.freqs, hi, side="right"))
        return np.asarray(self._cum[rows, j] - self._cum[rows, i])


def _clean(x: FloatArray) -> FloatArray | None:
    """``x`` with short gaps filled linearly and its line removed; None when more than a
    tenth is missing or it is constant."""
    bad = ~np.isfinite(x)
    if bad.any():
        if bad.mean() > 0.1:
            return None
        idx = np.arange(x.size)
        x = np.interp(idx, idx[~bad], x[~bad])
    y = detrend(np.asarray(x, dtype=np.float64))
    if not float(np.abs(y).max(initial=0.0)) > 1e-12 * max(float(np.abs(x).max()), 1e-300):
        return None
    return y


CHUNK = 256
"""Signals transformed at once (bounds the transform's temporaries)."""


def spectra(signals: FloatArray) -> Spectra:
    """The spectra of the rows of ``signals`` (signals x samples, one time base)."""
    m, n = signals.shape
    freqs = np.fft.rfftfreq(n)
    keep = freqs >= MIN_CYCLES / n  # up to Nyquist: the harmonics of a cycle count too
    taper = np.hanning(n)
    power = np.zeros((m, int(np.count_nonzero(keep))))
    usable = np.zeros(m, dtype=bool)
    for lo in range(0, m, CHUNK):
        rows = np.zeros((min(CHUNK, m - lo), n))
        for k in range(rows.shape[0]):
            y = _clean(signals[lo + k])
            if y is not None:
                rows[k] = y / float(np.std(y)) * taper
                usable[lo + k] = True
        spec = np.fft.rfft(rows, axis=1)[:, keep]
        power[lo:lo + rows.shape[0]] = spec.real ** 2 + spec.imag ** 2
    total = power.sum(axis=1, keepdims=True)
    np.divide(power, total, out=power, where=total > 0)
    cum = np.zeros((m, power.shape[1] + 1))
    np.cumsum(power, axis=1, out=cum[:, 1:])
    return Spectra(freqs[keep], power, usable, n, cum)
