"""One group judged: its members, their evidence, the ranking and the source
(:mod:`.source`, :mod:`.direction`, :mod:`.nonlinearity`, :mod:`.decide`).

The valve fit, direction and nonlinearity cost more than the rest (a Hammerstein search
per loop, a regression per pair of signals, a dozen surrogates per index), so a group of
hundreds of loops measures them for its leading candidates only: the valve of the
``VALVE_FITS`` loops with the most own evidence (called ``stiction`` first, then by
per-loop confidence and strength; others: no fit), direction for the ``CANDIDATES`` with
the most own evidence (verdict and valve), the ``STRONGEST`` loops that carry the cycle
most strongly and the ``INDICATORS`` indicators that do, the index for the ``NLI_LOOPS``
best of those after direction and for those indicators. The Granger gain between the
source and another member is measured when a decision needs it (a member called
``stiction``: does the source lead it?), every member's cycle filtered in one run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .._assessment import Assessment, Verdict
from .._validate import FloatArray
from .decide import Decision, IndicatorEvidence, decide
from .direction import cycle_band, cycle_bands, granger, phase_lag
from .groups import BAND, RawGroup, coherence_at
from .nonlinearity import nonlinearity
from .source import MemberEvidence, harmonics, member_evidence, rank
from .spectra import Spectra

__all__ = ["CANDIDATES", "INDICATORS", "NLI_LOOPS", "STRONGEST", "Judged", "Signals", "judge"]

CANDIDATES = 4
STRONGEST = 2
VALVE_FITS = 8
INDICATORS = 3
NLI_LOOPS = 3


@dataclasses.dataclass(frozen=True)
class Signals:
    """Every signal (rows: each loop's OP and PV, then the indicators), gaps bridged, and
    its spectrum."""

    rows: FloatArray
    spec: Spectra
    names: list[str]  # the loops, in row order
    row_of: dict[str, int]  # loop name -> its position in names (its OP is row 2 k)
    owner: list[str]  # each row's loop or indicator
    is_loop: list[bool]
    ts: float


@dataclasses.dataclass(frozen=True)
class Judged:
    """What :func:`judge` found: members (name, kind, strength), the loops' ranking, the
    indicators' evidence, the decision and the marginal signals (name, kind, strength)."""

    members: tuple[tuple[str, str, float], ...]
    ranking: tuple[MemberEvidence, ...]
    indicators: tuple[IndicatorEvidence, ...]
    decision: Decision
    marginal: tuple[tuple[str, str, float], ...] = ()


class _Links:
    """Each signal's band-passed cycle and the Granger gains between them, on demand."""

    def __init__(self, sigs: Signals, period: float, row: Mapping[str, int]) -> None:
        self.sigs, self.period, self.row = sigs, period, row
        self._series: dict[str, FloatArray] = {}
        self._gain: dict[tuple[str, str], float] = {}

    def series(self, name: str) -> FloatArray:
        z = self._series.get(name)
        if z is None:
            z = cycle_band(self.sigs.rows[self.row[name]], self.period)
            self._series[name] = z
        return z

    def prepare(self, names: list[str]) -> None:
        """The cycles of ``names`` at once (one filter run over all of them)."""
        todo = [n for n in names if n not in self._series]
        for lo in range(0, len(todo), 256):
            part = todo[lo:lo + 256]
            rows = self.sigs.rows[[self.row[n] for n in part]]
            self._series.update(zip(part, cycle_bands(rows, self.period), strict=True))

    def granger(self, a: str, b: str) -> float:
        g = self._gain.get((a, b))
        if g is None:
            g = granger(self.series(a), self.series(b))
            self._gain[a, b] = g
        return g

    def flow(self, a: str, b: str) -> float:
        return self.granger(a, b) - self.granger(b, a)

    def coherence(self, a: str, b: str) -> float:
        """Coherence of ``b``'s cycle with ``a``'s at the group's frequency."""
        rows = self.sigs.rows
        return float(coherence_at(rows[self.row[b]][None, :], rows[self.row[a]],
                                  1.0 / self.period)[0])


def _members(g: RawGroup, sigs: Signals, marginal: bool = False
             ) -> tuple[list[tuple[str, str, float]], dict[str, int]]:
    """(name, kind, strength) strongest first, and each member's strongest row; of the
    marginal signals with ``marginal`` (their owners that are no member)."""
    strength: dict[str, float] = {}
    row: dict[str, int] = {}
    kinds: dict[str, str] = {}
    pairs = zip(g.marginal, g.marginal_shares, strict=True) if marginal else \
        zip(g.signals, g.shares, strict=True)
    members = {sigs.owner[i] for i in g.signals} if marginal else set()
    for i, share in pairs:
        if sigs.owner[i] in members:
            continue
        nm = sigs.owner[i]
        if share > strength.get(nm, -1.0):
            strength[nm], row[nm] = share, i
        kinds[nm] = "loop" if sigs.is_loop[i] else "indicator"
    names = sorted(strength, key=lambda k: -strength[k])
    return [(nm, kinds[nm], strength[nm]) for nm in names], row


def _fitted(members: list[tuple[str, str, float]], assessments: Mapping[str, Assessment]
            ) -> set[str]:
    """The loops whose valve is fitted: the ``VALVE_FITS`` with the most own evidence
    (called ``stiction`` first, then by per-loop confidence, then by strength)."""
    def key(m: tuple[str, str, float]) -> tuple[bool, float, float]:
        a = assessments.get(m[0])
        return (a is not None and a.verdict == Verdict.STICTION,
                (a.confidence or 0.0) if a is not None else 0.0, m[2])

    loops = [m for m in members if m[1] == "loop"]
    return {m[0] for m in sorted(loops, key=key, reverse=True)[:VALVE_FITS]}


def _evidence(members: list[tuple[str, str, float]], row: dict[str, int], g: RawGroup,
              sigs: Signals, *, assessments: Mapping[str, Assessment],
              processes: Mapping[str, str]) -> list[MemberEvidence]:
    f0 = 1.0 / g.period
    fit = _fitted(members, assessments)
    out = []
    for name, kind, strength in members:
        if kind != "loop":
            continue
        k = sigs.row_of[name]  # not names.index: that made a big group quadratic
        harmonic = max(harmonics(sigs.spec, 2 * k, f0, f0 * BAND),
                       harmonics(sigs.spec, 2 * k + 1, f0, f0 * BAND))
        out.append(member_evidence(
            name, sigs.rows[2 * k], sigs.rows[2 * k + 1], ts=sigs.ts, period=g.period,
            integrating=processes.get(name) == "integrating", strength=strength,
            assessment=assessments.get(name), harmonic=harmonic,
            signal="op" if row[name] == 2 * k else "pv", fit=name in fit))
    return out


def _measured(evidence: list[MemberEvidence], indicators: list[IndicatorEvidence],
              links: _Links, *, row: Mapping[str, int], period: float
              ) -> tuple[list[MemberEvidence], list[IndicatorEvidence]]:
    """Direction for the leading candidates and indicators, then the nonlinearity index
    of the best of them (module doc)."""
    by_own = sorted(evidence, key=lambda e: -e.prescore)[:CANDIDATES]
    by_strength = sorted(evidence, key=lambda e: -e.strength)[:STRONGEST]
    cand = list(dict.fromkeys([e.loop for e in by_own + by_strength]))
    inds = [i.name for i in indicators[:INDICATORS]]
    pool = cand + inds
    flows = {a: (float(np.mean([links.flow(a, b) for b in pool if b != a]))
                 if len(pool) > 1 else 0.0) for a in pool}
    evidence = [dataclasses.replace(e, flow=flows.get(e.loop)) for e in evidence]
    best = {e.loop for e in sorted((e for e in evidence if e.flow is not None),
                                   key=lambda e: -e.score)[:NLI_LOOPS]}

    def nli(name: str) -> float | None:
        res = nonlinearity(links.sigs.rows[row[name]], period)
        return None if res is None else res.index

    evidence = [dataclasses.replace(e, nli=nli(e.loop)) if e.loop in best else e
                for e in evidence]
    indicators = [dataclasses.replace(i, flow=flows[i.name], nli=nli(i.name))
                  if i.name in flows else i for i in indicators]
    return evidence, indicators


def _lags(ranking: list[MemberEvidence], ref: str, sigs: Signals, row: Mapping[str, int],
          period: float) -> list[MemberEvidence]:
    a = sigs.rows[row[ref]]
    return [dataclasses.replace(e, lag_s=phase_lag(a, sigs.rows[row[e.loop]], period, sigs.ts))
            for e in ranking]


def judge(g: RawGroup, sigs: Signals, *, assessments: Mapping[str, Assessment],
          processes: Mapping[str, str], cascades: Mapping[str, str],
          previous: str | None = None) -> Judged:
    """The members of ``g``, their evidence and the source (module doc); ``previous``: the
    source this group had last round (hysteresis, :mod:`.decide`)."""
    members, row = _members(g, sigs)
    evidence = _evidence(members, row, g, sigs, assessments=assessments, processes=processes)
    indicators = [IndicatorEvidence(nm, s) for nm, kind, s in members if kind != "loop"]
    links = _Links(sigs, g.period, row)
    links.prepare([e.loop for e in evidence if e.called or e.valve_named])
    evidence, indicators = _measured(evidence, indicators, links, row=row, period=g.period)
    ranking = rank(evidence, dict(cascades))
    decision = decide(ranking, indicators, links.flow, links.granger, cascades=cascades,
                      previous=previous if previous in row else None,
                      coherence=links.coherence, period=g.period)
    ranking = _lags(ranking, decision.source or ranking[0].loop, sigs, row, g.period)
    return Judged(tuple(members), tuple(ranking), tuple(indicators), decision,
                  tuple(_members(g, sigs, marginal=True)[0]))
