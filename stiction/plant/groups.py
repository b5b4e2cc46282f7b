"""Which signals share an oscillation: seeds, clusters by period, members by band power.

1. **Seeds.** Every signal whose ACF shows a regular oscillation (Thornhill, Huang and
   Zhang 2003: regularity above ``SEED_REGULARITY``, the lobe one period out significant,
   :func:`stiction.signal.oscillation.detect_oscillation`) with a period of ``MIN_PERIOD``
   samples to a third of the window.
2. **Clusters.** Seeds sorted by period; a cluster takes the next seed while its period is
   within ``2 * BAND`` of the cluster's first (about linear in the signals: one sort).
3. **Members, with margins.** A cluster's band is its median frequency ``f0`` times
   ``1 -+ BAND``. Each signal (seed or not) is measured three ways: the share of its
   normalised spectrum in the band (``share``); how far the band stands above the spectrum
   around it, an octave either side with the band left out (``peak``: the cycle against
   the signal's own noise floor); and, for a signal that carries the cycle weakly, the
   coherence of its cycle with the cluster's strongest seed's (magnitude-squared
   coherence at ``f0``, Welch's estimate over ``SEGMENTS`` half-overlapping segments,
   when the window holds at least two cycles a segment: a load a good loop rejects well is
   weak in its spectrum but in step with its source). A signal passes a :class:`Bar` when
   its share reaches the bar's ``share``, or its share the bar's ``peak_share`` and its peak
   the bar's ``peak``, or its coherence the bar's ``coherence``. It is a **member** when it
   passes ``MEMBER`` (or is one of the cluster's seeds), a **stranger** when it does not
   pass ``STRANGER``, and **marginal** between the two: it may carry the cycle, but not
   clearly enough to take a role (it is listed with the group, its verdict untouched). The
   band between the bars is wide against the spread of each measure from one realisation
   of a plant to the next (issue 37: a loop joined at a coherence of 0.805 against 0.8 on
   one machine and not on another), so a loop that carries a cycle clearly is a member on
   every machine and one that hovers about a threshold is marginal, never a member on one
   and a stranger on the other. The band sums are two look-ups per signal
   (:class:`.spectra.Spectra`), so the cost grows with groups times signals, not with pairs
   of signals.

A group needs ``MIN_LOOPS`` loops among its members, ``MIN_SEED_LOOPS`` of them seeds; a
signal of no loop (an indicator) joins as what it is. Clusters whose bands overlap are
merged.

Hysteresis (``held``: the groups of the round before, the gateway's): where a cluster has
the period of a group held (within ``2 * BAND``), that group's members stay while they pass
``STRANGER`` and other signals join only when they pass ``MEMBER`` (the same band: a
marginal signal keeps what it was): a loop whose share of the cycle hovers about a
threshold neither joins nor leaves round after round (a stationary plant's one-hour windows
put a weak follower's share anywhere from 0.10 to 0.25 of its power in two hours of rounds:
tests/runtime/test_plant_story.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..signal.oscillation import Oscillation
from .spectra import MIN_CYCLES, MIN_PERIOD, Spectra

__all__ = ["BAND", "MEMBER", "MIN_LOOPS", "SEED_REGULARITY", "STRANGER", "Bar", "RawGroup",
           "coherence_at", "find_groups"]

BAND = 0.12
"""Half-width of a group's band, relative to its frequency (10-15 % is the usual tolerance
for 'the same period' in plant-wide studies)."""


@dataclasses.dataclass(frozen=True)
class Bar:
    """What a signal must show to pass (module doc, 3): a ``share`` of its power in the
    band; or a ``peak_share`` with the band ``peak`` times above the spectrum around it;
    or a ``coherence`` with the cluster's strongest seed at the cycle's frequency."""

    share: float
    peak_share: float
    peak: float
    coherence: float


MEMBER = Bar(share=0.25, peak_share=0.06, peak=6.0, coherence=0.9)
"""Clearly carries the cycle: a member. A coherence of 0.9 over 7 segments is far above
chance (0.54 at the 1 % level) and above what a loop two lags downstream of a follower
shows (0.3-0.8 for the named plant's PIC401 before issue 37 slowed its link)."""
STRANGER = Bar(share=0.1, peak_share=0.03, peak=3.0, coherence=0.6)
"""Below every part of this: a stranger to the cycle. Between the two bars: marginal."""
COHERENCE_FLOOR = 0.025
"""Share of the band under which a signal's coherence is not measured (it cannot be a
member by it: the cost of the coherence is kept to the signals that may be)."""
SEGMENTS = 7
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
    power in the band (``shares``, same order), and the marginal signals (module doc, 3)
    with theirs."""

    period: float
    signals: tuple[int, ...]
    shares: tuple[float, ...]
    marginal: tuple[int, ...] = ()
    marginal_shares: tuple[float, ...] = ()


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
        member, near = _standing(spec, period, cluster, allowed=allowed, signals=signals,
                                 was=was)
        picked = [int(i) for i in np.flatnonzero(member)]
        loops = {owner[i] for i in picked if is_loop[i]}
        seeded = {owner[i] for _, i in cluster if is_loop[i]}
        if len(loops) < MIN_LOOPS or len(seeded) < MIN_SEED_LOOPS:
            continue
        share = spec.band((1.0 - BAND) / period, (1.0 + BAND) / period)
        # a signal of an owner who is a member by another of its signals is no margin
        members = {owner[i] for i in picked}
        margin = [int(i) for i in np.flatnonzero(near) if owner[int(i)] not in members]
        groups.append(RawGroup(period, tuple(picked), tuple(float(share[i]) for i in picked),
                               tuple(margin), tuple(float(share[i]) for i in margin)))
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


def passes(bar: Bar, share: np.ndarray, peak: np.ndarray, coherence: np.ndarray
           ) -> np.ndarray:
    """Which signals pass ``bar`` (module doc, 3), from their share of the band, its peak
    over the spectrum around it and their coherence with the cluster's strongest seed."""
    return np.asarray((share >= bar.share) | ((share >= bar.peak_share) & (peak >= bar.peak))
                      | (coherence >= bar.coherence))


def _standing(spec: Spectra, period: float, cluster: list[tuple[float, int]], *,
              allowed: np.ndarray, signals: np.ndarray | None, was: np.ndarray | None
              ) -> tuple[np.ndarray, np.ndarray]:
    """(members, marginal) of the cluster's cycle (module doc, 3), with the hysteresis of
    ``was``: a member held stays while it passes ``STRANGER``."""
    f0 = 1.0 / period
    lo, hi = f0 * (1.0 - BAND), f0 * (1.0 + BAND)
    share = spec.band(lo, hi)
    around = (spec.band(f0 / 2.0, 2.0 * f0) - share) / _bins(spec, f0 / 2.0, 2.0 * f0, lo, hi)
    peak = share / np.maximum(around * _bins(spec, lo, hi), 1e-300)
    coh = np.zeros(share.size)
    if signals is not None:
        ref = max((i for _, i in cluster), key=lambda i: share[i])
        maybe = np.flatnonzero(allowed & (share >= COHERENCE_FLOOR) & (share < MEMBER.share))
        coh[maybe] = coherence_at(signals[maybe], signals[ref], f0)
    clear = passes(MEMBER, share, peak, coh)
    near = passes(STRANGER, share, peak, coh) & allowed
    member = clear if was is None else np.where(was, near, clear)
    member &= allowed
    for _, i in cluster:
        member[i] = True
    return np.asarray(member), np.asarray(near & ~member)


def _bins(spec: Spectra, lo: float, hi: float, cut_lo: float = 0.0, cut_hi: float = 0.0
          ) -> float:
    """Frequency bins between ``lo`` and ``hi``, less those between ``cut_lo`` and
    ``cut_hi`` (at least one)."""
    def count(a: float, b: float) -> int:
        return int(np.searchsorted(spec.freqs, b, side="right")
                   - np.searchsorted(spec.freqs, a, side="left"))
    return float(max(count(lo, hi) - (count(cut_lo, cut_hi) if cut_hi > cut_lo else 0), 1))


def _merged(groups: list[RawGroup]) -> list[RawGroup]:
    """Groups whose bands overlap become one (the larger one's period); a signal a member
    of either is a member, the margins of both less the members are the margin."""
    out: list[RawGroup] = []
    for g in sorted(groups, key=lambda g: g.period):
        if out and g.period <= out[-1].period * (1.0 + BAND) / (1.0 - BAND):
            a, b = out[-1], g
            keep = a if len(a.signals) >= len(b.signals) else b
            shares = dict(zip(b.signals, b.shares, strict=True))
            shares.update(dict(zip(a.signals, a.shares, strict=True)))
            near = dict(zip(b.marginal, b.marginal_shares, strict=True))
            near.update(dict(zip(a.marginal, a.marginal_shares, strict=True)))
            rows = sorted(shares)
            margin = sorted(set(near) - set(shares))
            out[-1] = RawGroup(keep.period, tuple(rows), tuple(shares[i] for i in rows),
                               tuple(margin), tuple(near[i] for i in margin))
        else:
            out.append(g)
    return out
