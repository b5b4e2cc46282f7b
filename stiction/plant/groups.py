"""Which signals share an oscillation: seeds, clusters by period, members by band power.

1. **Seeds.** Every signal whose ACF shows a regular oscillation (Thornhill, Huang and
   Zhang 2003: regularity above ``SEED_REGULARITY``, the lobe one period out significant,
   :func:`stiction.signal.oscillation.detect_oscillation`) with a period of ``MIN_PERIOD``
   samples to a third of the window.
2. **Clusters.** Seeds sorted by period; a cluster takes the next seed while its period is
   within ``2 * BAND`` of the cluster's first (about linear in the signals: one sort).
3. **Members.** A cluster's band is its median frequency ``f0`` times ``1 -+ BAND``; every
   signal (seed or not) whose normalised spectrum holds at least ``SHARE`` of its power in
   that band carries the cycle (how strongly: that share). The band sums are two look-ups
   per signal (:class:`.spectra.Spectra`), so the cost grows with groups times signals,
   not with pairs of signals. A signal that holds at least ``PEAK_SHARE`` but not enough
   to join by its share joins when its cycle is coherent with the cluster's strongest
   seed's (magnitude-squared coherence at the cluster's frequency at least ``COHERENT``,
   Welch's estimate over ``SEGMENTS`` half-overlapping segments, when the window holds
   at least two cycles a segment): a load a good loop rejects well is weak in its
   spectrum but in step with its source.

A group needs ``MIN_LOOPS`` loops among its members, ``MIN_SEED_LOOPS`` of them seeds; a
signal of no loop (an indicator) joins as what it is. Clusters whose bands overlap are
merged.

Hysteresis (``held``: the groups of the round before, the gateway's): where a cluster has
the period of a group held (within ``2 * BAND``), that group's members stay with thresholds
``KEEP`` times as low (coherence ``COHERENCE_MARGIN`` lower) and other signals join only
with thresholds ``JOIN`` times as high (coherence as much higher): a loop whose share of the
cycle hovers about a threshold neither joins nor leaves round after round (a stationary
plant's one-hour windows put a weak follower's share anywhere from 0.10 to 0.25 of its
power in two hours of rounds: tests/runtime/test_plant_story.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..signal.oscillation import Oscillation
from .spectra import MIN_CYCLES, MIN_PERIOD, Spectra

__all__ = ["BAND", "COHERENT", "MIN_LOOPS", "SEED_REGULARITY", "SHARE", "RawGroup",
           "coherence_at", "find_groups"]

BAND = 0.12
"""Half-width of a group's band, relative to its frequency (10-15 % is the usual tolerance
for 'the same period' in plant-wide studies)."""
SHARE = 0.2
"""Share of a signal's power in a group's band from which it carries the group's cycle."""
PEAK_SHARE = 0.05
"""A smaller share counts too when the band stands ``PEAK`` times above the spectrum around
it (an octave either side, the band left out): a cycle a noisy or load-driven signal
carries weakly but clearly."""
PEAK = 5.0
COHERENT = 0.8
SEGMENTS = 7
KEEP, JOIN, COHERENCE_MARGIN = 0.5, 1.5, 0.1
SEED_REGULARITY = 1.0
"""Thornhill's regularity a seed needs (r > 1: a regular oscillation)."""
MIN_LOOPS = 2
MIN_SEED_LOOPS = 1
"""Loops whose own OP or PV oscillates regularly at the group's period (seeds) a group
needs. Two would drop most groups that are only a slow wander two loops happen to share
(2 of 60 quiet plants, 7 of 60 tuning plants) but also real ones (source first: 66 of 76
instead of 69); a group without a named source turns no verdict into ``stiction``, so one
seed it is."""


@dataclasses.dataclass(frozen=True)
class RawGroup:
    """A shared oscillation: ``period`` in samples, its member signals with their share of
    power in the band (``shares``, same order)."""

    period: float
    signals: tuple[int, ...]
    shares: tuple[float, ...]


def _clusters(periods: list[tuple[float, int]]) -> list[list[tuple[float, int]]]:
    out: list[list[tuple[float, int]]] = []
    for p, i in sorted(periods):
        if out and p <= out[-1][0][0] * (1.0 + 2.0 * BAND):
            out[-1].append((p, i))
        else:
            out.append([(p, i)])
    return out


def coherence_at(x: np.ndarray, ref: np.ndarray, f0: float) -> np.ndarray:
    """Magnitude-squared coherence of each row of ``x`` with ``ref`` at ``f0`` (cycles per
    sample), Welch's estimate over ``SEGMENTS`` half-overlapping Hann segments; zeros when
    a segment would hold fewer than two cycles."""
    n = ref.size
    length = int(2 * n / (SEGMENTS + 1))
    if length * f0 < 2.0 or x.shape[0] == 0:
        return np.zeros(x.shape[0])
    t = np.arange(length)
    basis = np.hanning(length) * np.exp(-2j * np.pi * round(f0 * length) * t / length)
    starts = range(0, n - length + 1, length // 2)
    r = np.array([(ref[s:s + length] - ref[s:s + length].mean()) @ basis for s in starts])
    xs = np.stack([(x[:, s:s + length] - x[:, s:s + length].mean(axis=1, keepdims=True))
                   @ basis for s in starts], axis=1)
    cross = np.abs(xs @ np.conj(r)) ** 2
    power = (np.abs(xs) ** 2).sum(axis=1) * float((np.abs(r) ** 2).sum())
    return np.asarray(np.divide(cross, power, out=np.zeros_like(cross), where=power > 0))


def find_groups(spec: Spectra, oscillations: Sequence[Oscillation | None],
                owner: Sequence[str], is_loop: Sequence[bool], *,
                rows: np.ndarray | None = None, signals: np.ndarray | None = None,
                held: Sequence[tuple[float, set[str]]] = ()) -> list[RawGroup]:
    """The shared oscillations among the signals of ``spec``: ``oscillations[i]`` is
    signal ``i``'s ACF oscillation (None when not analysed), ``owner[i]`` its loop or
    indicator name, ``is_loop[i]`` whether that owner is a loop; ``rows`` (a mask) the
    signals that may take part (one unit's), all when None; ``signals`` the series (rows
    as in ``spec``, gaps bridged) for the coherence test, none when None; ``held`` the
    groups of the round before as (period in samples, member names)."""
    longest = spec.n / MIN_CYCLES
    allowed = spec.usable if rows is None else spec.usable & rows
    seeds = [(float(o.period), i) for i, o in enumerate(oscillations)
             if allowed[i] and o is not None and o.oscillating and o.period is not None
             and o.regularity > SEED_REGULARITY and MIN_PERIOD <= o.period <= longest]
    groups: list[RawGroup] = []
    for cluster in _clusters(seeds):
        period = float(np.median([p for p, _ in cluster]))
        was = _was(period, held, owner)
        member = _members(spec, period, cluster, allowed=allowed, signals=signals, was=was)
        picked = [int(i) for i in np.flatnonzero(member)]
        loops = {owner[i] for i in picked if is_loop[i]}
        seeded = {owner[i] for _, i in cluster if is_loop[i]}
        if len(loops) < MIN_LOOPS or len(seeded) < MIN_SEED_LOOPS:
            continue
        share = spec.band((1.0 - BAND) / period, (1.0 + BAND) / period)
        groups.append(RawGroup(period, tuple(picked),
                               tuple(float(share[i]) for i in picked)))
    return _merged(groups)


def _was(period: float, held: Sequence[tuple[float, set[str]]], owner: Sequence[str]
         ) -> np.ndarray | None:
    """Per signal: was its owner a member of the held group of this period (None: no
    such group)?"""
    near = [(abs(p / period - 1.0), names) for p, names in held
            if abs(p / period - 1.0) <= 2.0 * BAND]
    if not near:
        return None
    names = min(near, key=lambda x: x[0])[1]
    return np.array([o in names for o in owner])


def _members(spec: Spectra, period: float, cluster: list[tuple[float, int]], *,
             allowed: np.ndarray, signals: np.ndarray | None, was: np.ndarray | None
             ) -> np.ndarray:
    """Which signals carry the cluster's cycle (module doc), with the hysteresis of
    ``was``."""
    f0 = 1.0 / period
    lo, hi = f0 * (1.0 - BAND), f0 * (1.0 + BAND)
    share = spec.band(lo, hi)
    around = (spec.band(f0 / 2.0, 2.0 * f0) - share) / _bins(spec, f0 / 2.0, 2.0 * f0, lo, hi)
    peak = share / np.maximum(around * _bins(spec, lo, hi), 1e-300)
    coh = np.zeros(share.size)
    if signals is not None:
        ref = max((i for _, i in cluster), key=lambda i: share[i])
        maybe = np.flatnonzero(allowed & (share >= PEAK_SHARE * KEEP) & (share < SHARE))
        coh[maybe] = coherence_at(signals[maybe], signals[ref], f0)

    def by(k: float, dc: float) -> np.ndarray:
        return (share >= SHARE * k) | ((share >= PEAK_SHARE * k) & (peak >= PEAK * k)) | \
            (coh >= COHERENT + dc)

    member = by(1.0, 0.0) if was is None else \
        np.where(was, by(KEEP, -COHERENCE_MARGIN), by(JOIN, COHERENCE_MARGIN))
    member &= allowed
    for _, i in cluster:
        member[i] = True
    return np.asarray(member)


def _bins(spec: Spectra, lo: float, hi: float, cut_lo: float = 0.0, cut_hi: float = 0.0
          ) -> float:
    """Frequency bins between ``lo`` and ``hi``, less those between ``cut_lo`` and
    ``cut_hi`` (at least one)."""
    def count(a: float, b: float) -> int:
        return int(np.searchsorted(spec.freqs, b, side="right")
                   - np.searchsorted(spec.freqs, a, side="left"))
    return float(max(count(lo, hi) - (count(cut_lo, cut_hi) if cut_hi > cut_lo else 0), 1))


def _merged(groups: list[RawGroup]) -> list[RawGroup]:
    """Groups whose bands overlap become one (the larger one's period)."""
    out: list[RawGroup] = []
    for g in sorted(groups, key=lambda g: g.period):
        if out and g.period <= out[-1].period * (1.0 + BAND) / (1.0 - BAND):
            a, b = out[-1], g
            keep = a if len(a.signals) >= len(b.signals) else b
            shares = dict(zip(b.signals, b.shares, strict=True))
            shares.update(dict(zip(a.signals, a.shares, strict=True)))
            rows = sorted(shares)
            out[-1] = RawGroup(keep.period, tuple(rows), tuple(shares[i] for i in rows))
        else:
            out.append(g)
    return out
