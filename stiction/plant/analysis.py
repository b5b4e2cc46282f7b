"""``analyze_plant``: many loops on one time base in, the oscillations they share out.

1. Every signal's spectrum and ACF oscillation (:mod:`.spectra`,
   :func:`stiction.signal.oscillation.detect_oscillations`).
2. The groups that share an oscillation (:mod:`.groups`): a period, its members and how
   strongly each carries it.
3. In each group, the members ranked as its source (:mod:`.source`); the top one named
   the source when its own valve evidence is enough, else the group has no loop source.
4. Per loop, its role: ``source``, ``follower`` or none (not in any group); a loop in two
   groups takes its role from the one it carries most strongly. Besides the named source,
   a member whose own valve evidence would name it too is a source of its own (two sticky
   valves at one period): its ``LoopRole.source`` is itself.

:meth:`PlantAssessment.apply` turns the per-loop assessments into plant-aware ones: a
follower called ``stiction`` becomes ``propagated`` (the reason names the source, or says
there is none among the loops, and the shared period); a named source keeps its verdict
and size, and so does the top candidate of a group with no source named unless an
indicator carries the cycle about as strongly as the strongest loop (the plant view has no better
explanation than its own valve: on the TEP plant runs, demoting it lost 37 of the sticking
valves' calls); a loop in no group keeps its assessment.
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
from .groups import BAND, RawGroup, find_groups
from .source import MemberEvidence, harmonics, member_evidence, named_source, rank
from .spectra import Spectra, spectra

__all__ = ["Group", "LoopRole", "Member", "PlantAssessment", "analyze_plant"]

ROLES = ("source", "follower")
OUTSIDE = 0.9
"""A group's cycle is seen entering from outside the loops when a signal that is no loop's
carries it at least this share of the strongest loop's strength (:attr:`Group.outside`)."""


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
    first), ``source`` (a loop, or None when no loop is the source) and the ``reason``."""

    number: int
    period_s: float
    members: tuple[Member, ...]
    ranking: tuple[MemberEvidence, ...]
    source: str | None
    reason: str
    also_sources: tuple[str, ...] = ()
    """Loops besides ``source`` whose own valve evidence names them a source too: a second
    sticky valve cycling at the same period (two flow loops with one valve model on one
    PLC), which a shared period alone cannot tell from a follower. Never a declared outer
    loop of a cascade (its inner loop's valve moves it), never in a group without a loop
    source."""

    @property
    def loops(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.members if m.kind == "loop")

    @property
    def external(self) -> bool:
        """No loop analysed is the source: the cycle enters from outside."""
        return self.source is None

    @property
    def outside(self) -> bool:
        """A signal that is no loop's carries the cycle about as strongly as the strongest
        loop, at least :data:`OUTSIDE` of it (a header pressure, a utility temperature): the
        cycle is seen entering from there."""
        loops = [m.strength for m in self.members if m.kind == "loop"]
        others = [m.strength for m in self.members if m.kind != "loop"]
        return bool(others) and max(others) >= OUTSIDE * max(loops, default=0.0)


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
    """The groups and every loop's role."""

    groups: tuple[Group, ...]
    roles: Mapping[str, LoopRole]

    def group(self, number: int) -> Group:
        return next(g for g in self.groups if g.number == number)

    def apply(self, assessments: Mapping[str, Assessment]) -> dict[str, Assessment]:
        """The per-loop assessments with the plant view: a follower's ``stiction`` becomes
        ``propagated`` (no size: it is not its valve's), but for the top candidate of a
        group with no source named; everything else unchanged."""
        out = dict(assessments)
        for name, a in assessments.items():
            role = self.roles.get(name)
            if role is None or role.role != "follower" or a.verdict != Verdict.STICTION:
                continue
            g = self.group(role.group or 0)
            if g.source is None and g.ranking[0].loop == name and not g.outside:
                continue  # the likeliest source of a group with none named: its own call
            where = (f"its source is {g.source}" if g.source is not None else
                     "its source is no loop analysed here (a cycle from outside, or from a "
                     "loop not read)")
            out[name] = dataclasses.replace(
                a, verdict=Verdict.PROPAGATED, fd=None, fs=None, jump=None, fd_op=None,
                fs_op=None, cycles_used=0, multi_jump=False,
                reason=f"propagated: the cycle of {g.period_s:.0f} s is shared by "
                       f"{len(g.loops)} loops and {where}; this loop's own tests said "
                       f"stiction at {a.confidence or 0.0:.2f}")
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


def analyze_plant(
    loops: Mapping[str, tuple[ArrayLike, ArrayLike]],
    *,
    ts: float,
    indicators: Mapping[str, ArrayLike] | None = None,
    assessments: Mapping[str, Assessment] | None = None,
    processes: Mapping[str, str] | None = None,
    cascades: Mapping[str, str] | None = None,
) -> PlantAssessment:
    """The oscillations ``loops`` share and their sources.

    Parameters
    ----------
    loops
        Loop name -> (OP, PV), every series of one length on one time base (NaN: gaps).
    ts
        Sample time, s.
    indicators
        Other measured signals (no loop's), name -> series: they join groups and show where
        a cycle is, but are never named its source.
    assessments
        The loops' per-loop assessments (:func:`stiction.analyze`): their confidence
        breaks near-ties and a named source needs one of at least ``SOURCE_CONFIDENCE``.
        Without them no source is named (the ranking still is).
    processes
        Loop name -> "self-regulating" (default) or "integrating".
    cascades
        Outer loop name -> inner loop name, for cascades: the inner loop's valve is the
        outer loop's.
    """
    if not ts > 0:
        raise ParameterError("ts", f"must be > 0, was {ts!r}")
    names = list(loops)
    inds = dict(indicators or {})
    n: int | None = None
    rows: list[FloatArray] = []
    for name in names:
        op, pv = loops[name]
        a = _series(f"loops[{name!r}] OP", op, n)
        n = a.size
        rows += [a, _series(f"loops[{name!r}] PV", pv, n)]
    rows += [_series(f"indicators[{k!r}]", v, n) for k, v in inds.items()]
    if not rows:
        return PlantAssessment((), {})
    owner = [nm for nm in names for _ in (0, 1)] + list(inds)
    is_loop = [True] * (2 * len(names)) + [False] * len(inds)
    signals = np.array(rows)
    spec = spectra(signals)
    finite = np.isfinite(signals).all(axis=1)
    oscs = detect_oscillations([signals[i] for i in np.flatnonzero(finite & spec.usable)])
    by_row: list[Oscillation | None] = [None] * len(rows)
    for i, o in zip(np.flatnonzero(finite & spec.usable), oscs, strict=True):
        by_row[int(i)] = o
    raw = find_groups(spec, by_row, owner, is_loop)
    sigs = _Signals(signals, spec, names, {nm: k for k, nm in enumerate(names)}, owner, is_loop)
    groups = [_group(k + 1, g, sigs, ts=ts, assessments=assessments or {},
                     processes=processes or {}, cascades=dict(cascades or {}))
              for k, g in enumerate(raw)]
    return PlantAssessment(tuple(groups), _roles(names, groups))


@dataclasses.dataclass(frozen=True)
class _Signals:
    """Every signal (rows: each loop's OP and PV, then the indicators) and its spectrum."""

    rows: FloatArray
    spec: Spectra
    names: list[str]  # the loops, in row order
    row_of: dict[str, int]  # loop name -> its position in names (its OP is row 2 k)
    owner: list[str]  # each row's loop or indicator
    is_loop: list[bool]


def _group(number: int, g: RawGroup, sigs: _Signals, *, ts: float,
           assessments: Mapping[str, Assessment], processes: Mapping[str, str],
           cascades: dict[str, str]) -> Group:
    owner, is_loop, spec, signals = sigs.owner, sigs.is_loop, sigs.spec, sigs.rows
    strength: dict[str, float] = {}
    kinds: dict[str, str] = {}
    for i, share in zip(g.signals, g.shares, strict=True):
        strength[owner[i]] = max(strength.get(owner[i], 0.0), share)
        kinds[owner[i]] = "loop" if is_loop[i] else "indicator"
    members = tuple(Member(nm, kinds[nm], strength[nm])
                    for nm in sorted(strength, key=lambda k: -strength[k]))
    f0 = 1.0 / g.period
    evidence = []
    for m in members:
        if m.kind != "loop":
            continue
        k = sigs.row_of[m.name]  # not names.index: that made a big group quadratic
        harmonic = max(harmonics(spec, 2 * k, f0, f0 * BAND),
                       harmonics(spec, 2 * k + 1, f0, f0 * BAND))
        evidence.append(member_evidence(
            m.name, signals[2 * k], signals[2 * k + 1], ts=ts, period=g.period,
            integrating=processes.get(m.name) == "integrating", strength=m.strength,
            assessment=assessments.get(m.name), harmonic=harmonic))
    ranking = rank(evidence, cascades)
    top = ranking[0]
    period_s = g.period * ts
    if named_source(top):
        reason = (f"{top.loop} is the source of the {period_s:.0f} s cycle shared by "
                  f"{len(evidence)} loops: {top.note()}")
        also = tuple(e.loop for e in ranking[1:] if named_source(e) and e.loop not in cascades)
        return Group(number, period_s, members, tuple(ranking), top.loop, reason, also)
    reason = (f"no loop analysed here is the source of the {period_s:.0f} s cycle shared by "
              f"{len(evidence)} loops (best candidate {top.loop}: {top.note()}): it enters "
              "from outside, or from a loop not read")
    return Group(number, period_s, members, tuple(ranking), None, reason)


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
            else:
                roles[m.name] = LoopRole(m.name, g.number, "follower", g.source)
    return roles
