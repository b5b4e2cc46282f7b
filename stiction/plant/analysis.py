"""``analyze_plant``: many loops on one time base in, the oscillations they share out.

1. Every signal's gaps bridged (:mod:`.gaps`: a signal with a long gap leaves, with its
   reason), its spectrum and ACF oscillation (:mod:`.spectra`,
   :func:`stiction.signal.oscillation.detect_oscillations`).
2. The groups that share an oscillation (:mod:`.groups`), within each unit when loops are
   given units (loops of independent units that happen to share a period are not one
   group): a period, its members and how strongly each carries it.
3. In each group the members' evidence, their ranking as its source and the decision
   (:mod:`.judge`, :mod:`.source`, :mod:`.decide`): a loop named its source and which
   evidence named it, or an indicator it enters by from outside, or no source.
4. Per loop, its role: ``source``, ``follower`` or none (not in any group, or a member
   called ``stiction`` whose call the group's evidence does not overturn: *kept*); a loop in
   two groups takes its role from the one it carries most strongly. Besides the named
   source, a member whose own verdict or valve names it and who does not follow the source
   is a source of its own (two sticky valves at one period).

:meth:`PlantAssessment.apply` tells one story per loop (:mod:`.story`): a follower is never
``stiction`` (it becomes ``propagated``: the reason names the source, or the indicator the
cycle enters by, and the evidence); a source keeps its verdict and size; a kept loop keeps
its verdict, its reason names the group; a loop in no group keeps its assessment.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from .._assessment import Assessment, Verdict
from .._errors import ParameterError
from .._validate import FloatArray
from ..signal.oscillation import Oscillation, detect_oscillations
from .decide import IndicatorEvidence
from .gaps import bridged
from .groups import RawGroup, find_groups
from .judge import Judged, Signals, judge
from .source import MemberEvidence
from .spectra import spectra
from .story import group_reason, kept, propagated

__all__ = ["Group", "LoopRole", "Member", "PlantAssessment", "analyze_plant"]

ROLES = ("source", "follower")


@dataclasses.dataclass(frozen=True)
class Member:
    """A signal in a group: ``kind`` "loop" or "indicator", ``strength`` the share of its
    power in the group's band (a loop: the larger of OP's and PV's)."""

    name: str
    kind: str
    strength: float


@dataclasses.dataclass(frozen=True)
class Group:
    """One oscillation shared by several loops: ``number`` (1, 2, ... by period),
    ``period_s``, its ``members``, the ``ranking`` of its loops as source candidates (best
    first, each with its evidence), ``source`` (a loop, or None), the ``reason``, the
    evidence that named the source (``named_by``), the indicator the cycle enters by from
    outside (``entry``), why each loop called ``stiction`` that is not a source follows
    (``demoted``), the indicators' evidence and the ``unit``."""

    number: int
    period_s: float
    members: tuple[Member, ...]
    ranking: tuple[MemberEvidence, ...]
    source: str | None
    reason: str
    also_sources: tuple[str, ...] = ()
    """Loops besides ``source`` whose own verdict or valve names them a source and whom
    the source does not lead: a second sticky valve cycling at the same period (two flow
    loops with one valve model on one PLC). Never a declared outer loop of a cascade."""
    named_by: tuple[str, ...] = ()
    entry: str | None = None
    demoted: Mapping[str, str] = dataclasses.field(default_factory=dict)
    indicators: tuple[IndicatorEvidence, ...] = ()
    unit: str = ""
    marginal: tuple[Member, ...] = ()
    """Signals that may carry the cycle but not clearly enough to be members
    (:mod:`.groups`): listed, no role, their verdicts untouched."""
    kept: Mapping[str, str] = dataclasses.field(default_factory=dict)
    """Members called ``stiction`` that are neither a source nor a follower (loop -> why):
    their call stands (an indicator's lead alone never overturns it), no role."""
    upstream: str | None = None
    """An indicator that leads the cycle while a loop is its source, not strongly enough to
    outweigh that loop's own evidence: the group is also fed from outside, check upstream."""

    @property
    def loops(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.members if m.kind == "loop")

    @property
    def external(self) -> bool:
        """No loop analysed is the source."""
        return self.source is None

    @property
    def outside(self) -> bool:
        """The cycle enters from outside the loops, by indicator :attr:`entry`."""
        return self.entry is not None


@dataclasses.dataclass(frozen=True)
class LoopRole:
    """A loop's place in the plant view: its ``group`` number and ``role`` ("source",
    "follower"), both None when it shares no oscillation."""

    loop: str
    group: int | None = None
    role: str | None = None
    source: str | None = None


@dataclasses.dataclass(frozen=True)
class PlantAssessment:
    """The groups, every loop's role, and the signals left out (name -> why)."""

    groups: tuple[Group, ...]
    roles: Mapping[str, LoopRole]
    left_out: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def group(self, number: int) -> Group:
        return next(g for g in self.groups if g.number == number)

    def apply(self, assessments: Mapping[str, Assessment]) -> dict[str, Assessment]:
        """The per-loop assessments with the plant view: a follower's ``stiction`` becomes
        ``propagated`` (no size: it is not its valve's); a kept loop's reason names the
        group it shares a cycle with; everything else unchanged."""
        out = dict(assessments)
        for name, a in assessments.items():
            role = self.roles.get(name)
            if role is None or role.group is None or a.verdict != Verdict.STICTION:
                continue
            g = self.group(role.group)
            if role.role == "follower":
                out[name] = propagated(g, name, a)
            elif role.role is None and name in g.kept:
                out[name] = kept(g, name, a)
        return out


def _series(name: str, value: ArrayLike, n: int | None) -> FloatArray:
    try:
        x = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "must be a sequence of numbers") from exc
    if x.ndim != 1 or (n is not None and x.size != n):
        raise ParameterError(name, f"must be 1-D with {n} samples like the others, has "
                                   f"shape {x.shape}")
    return x


def _rows(loops: Mapping[str, tuple[ArrayLike, ArrayLike]], inds: Mapping[str, ArrayLike]
          ) -> tuple[FloatArray, dict[str, str]]:
    """Every signal checked and its gaps bridged, as the rows of one matrix (each loop's OP
    and PV, then the indicators; a loop with a long gap in OP or PV is left out whole: both
    rows NaN); name -> why for those left out."""
    signals: list[tuple[str, list[tuple[str, ArrayLike]]]] = [
        (name, [(f"loops[{name!r}] OP", op), (f"loops[{name!r}] PV", pv)])
        for name, (op, pv) in loops.items()]
    signals += [(name, [(f"indicators[{name!r}]", x)]) for name, x in inds.items()]
    out: FloatArray | None = None
    left: dict[str, str] = {}
    i = 0
    for name, parts in signals:
        xs = [_series(label, x, None if out is None else out.shape[1]) for label, x in parts]
        if out is None:
            out = np.empty((2 * len(loops) + len(inds), xs[0].size))
        fixed = [bridged(x) for x in xs]
        bad = [(label.rsplit(" ", 1)[-1] + ": " if len(parts) == 2 else "") + why
               for (label, _x), (_y, why) in zip(parts, fixed, strict=True) if why]
        if bad:
            left[name] = "; ".join(bad)
        for y, _why in fixed:
            out[i] = np.nan if bad or y is None else y
            i += 1
    return (np.empty((0, 0)) if out is None else out), left


def analyze_plant(
    loops: Mapping[str, tuple[ArrayLike, ArrayLike]],
    *,
    ts: float,
    indicators: Mapping[str, ArrayLike] | None = None,
    assessments: Mapping[str, Assessment] | None = None,
    processes: Mapping[str, str] | None = None,
    cascades: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    previous: PlantAssessment | None = None,
) -> PlantAssessment:
    """The oscillations ``loops`` share and their sources.

    Parameters
    ----------
    loops
        Loop name -> (OP, PV), every series of one length on one time base (NaN: gaps).
    ts
        Sample time, s.
    indicators
        Other measured signals (no loop's), name -> series: they join groups, show where
        a cycle is and may show it entering from outside, but are never named its source.
    assessments
        The loops' per-loop assessments (:func:`stiction.analyze`): their verdicts and
        confidence are evidence (a loop called ``stiction`` in a group is its source unless
        other evidence says otherwise). Without them no loop's own verdict counts.
    processes
        Loop name -> "self-regulating" (default) or "integrating".
    cascades
        Outer loop name -> inner loop name, for cascades: the inner loop's valve is the
        outer loop's.
    units
        Loop or indicator name -> its unit: groups form within a unit (an indicator
        without one may join any unit's groups). None or empty: one unit.
    previous
        The last round's assessment of the same loops (the gateway): a group's members stay
        with lower thresholds and others join with higher ones (:mod:`.groups`), a source
        named then stays while its evidence stands (:mod:`.decide`).
    """
    if not ts > 0:
        raise ParameterError("ts", f"must be > 0, was {ts!r}")
    names = list(loops)
    inds = dict(indicators or {})
    signals, left = _rows(loops, inds)
    if not signals.size:
        return PlantAssessment((), {})
    owner = [nm for nm in names for _ in (0, 1)] + list(inds)
    is_loop = [True] * (2 * len(names)) + [False] * len(inds)
    spec = spectra(signals)
    usable = np.isfinite(signals).all(axis=1) & spec.usable
    oscs = detect_oscillations([signals[i] for i in np.flatnonzero(usable)])
    by_row: list[Oscillation | None] = [None] * signals.shape[0]
    for i, o in zip(np.flatnonzero(usable), oscs, strict=True):
        by_row[int(i)] = o
    unit_of = dict(units or {})
    held = [] if previous is None else [(g.period_s / ts, {m.name for m in g.members})
                                        for g in previous.groups]
    raw: list[tuple[str, RawGroup]] = []
    for unit in sorted({unit_of.get(nm, "") for nm in names}):
        rows_in = np.array([(unit_of.get(o, "") == unit) or (not loop and o not in unit_of)
                            for o, loop in zip(owner, is_loop, strict=True)])
        raw += [(unit, g) for g in find_groups(spec, by_row, owner, is_loop, rows=rows_in,
                                                  signals=signals, held=held)]
    raw.sort(key=lambda x: (x[1].period, x[0]))
    sigs = Signals(signals, spec, names, {nm: k for k, nm in enumerate(names)}, owner,
                   is_loop, ts)
    before = {} if previous is None else {frozenset(g.loops): g.source for g in previous.groups}
    groups = []
    for k, (unit, g) in enumerate(raw):
        loops_in = {owner[i] for i in g.signals if is_loop[i]}
        prev = max(before.items(), key=lambda kv: len(kv[0] & loops_in), default=(None, None))
        j = judge(g, sigs, assessments=assessments or {}, processes=processes or {},
                  cascades=dict(cascades or {}),
                  previous=prev[1] if prev[0] and prev[0] & loops_in else None)
        groups.append(_group(k + 1, g.period * ts, j, unit))
    return PlantAssessment(tuple(groups), _roles(names, groups), left)


def _group(number: int, period_s: float, j: Judged, unit: str) -> Group:
    d = j.decision
    members = tuple(Member(nm, kind, s) for nm, kind, s in j.members)
    n = sum(1 for m in members if m.kind == "loop")
    reason = group_reason(period_s, n, j.ranking, j.indicators, d)
    return Group(number, period_s, members, j.ranking, d.source, reason, d.also, d.named_by,
                 d.outside, dict(d.demoted), j.indicators, unit,
                 tuple(Member(nm, kind, s) for nm, kind, s in j.marginal), dict(d.kept),
                 d.upstream)


def _roles(names: list[str], groups: list[Group]) -> dict[str, LoopRole]:
    roles = {nm: LoopRole(nm) for nm in names}
    best: dict[str, float] = {}
    for g in groups:
        for m in g.members:
            if m.kind != "loop" or m.strength <= best.get(m.name, -1.0):
                continue
            best[m.name] = m.strength
            if m.name == g.source or m.name in g.also_sources:
                roles[m.name] = LoopRole(m.name, g.number, "source", m.name)
            elif m.name in g.kept:
                roles[m.name] = LoopRole(m.name, g.number, None, g.source)
            else:
                roles[m.name] = LoopRole(m.name, g.number, "follower", g.source)
    return roles
