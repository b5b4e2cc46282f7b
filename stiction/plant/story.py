"""The plant view in words: a group's reason, a follower's ``propagated`` and a kept loop's
note (one story per loop, the evidence named with its figure).

Where the source named is a loop whose own window says ``no_stiction``, the reason says what
the evidence points to instead of its valve (issue 37): a nonlinear cycle that is not the
valve's (a limit, an on/off or split-range element, a process nonlinearity), or, with a
linear cycle, the loop's tuning or a disturbance entering at it; where its valve fit speaks
for a sticky valve against its own window, a step test in manual tells the two apart.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Protocol

from .._assessment import Assessment, Verdict
from .decide import Decision, IndicatorEvidence
from .nonlinearity import NLI_NONLINEAR
from .source import SOURCE_SCORE, MemberEvidence

__all__ = ["group_reason", "kept", "propagated"]


class Group(Protocol):
    """What a story reads of :class:`stiction.plant.analysis.Group` (a protocol, so this
    module need not import the one that imports it)."""

    @property
    def number(self) -> int: ...
    @property
    def period_s(self) -> float: ...
    @property
    def source(self) -> str | None: ...
    @property
    def named_by(self) -> tuple[str, ...]: ...
    @property
    def entry(self) -> str | None: ...
    @property
    def demoted(self) -> Mapping[str, str]: ...
    @property
    def kept(self) -> Mapping[str, str]: ...
    @property
    def loops(self) -> tuple[str, ...]: ...


def _ind(ind: IndicatorEvidence) -> str:
    nli = "" if ind.nli is None else f", nonlinearity index {ind.nli:.1f}"
    return f"Granger net flow {ind.flow or 0.0:+.2f}{nli}"


def instead(src: MemberEvidence) -> str:
    """What a source's evidence points to where its own window says ``no_stiction``."""
    if src.valve >= SOURCE_SCORE:
        return (f"its own window says {src.verdict} while a sticky valve explains its PV: "
                "a step test in manual tells the two apart")
    if src.nli is not None and src.nli > NLI_NONLINEAR:
        return (f"its own window says {src.verdict}, so its nonlinear cycle points to "
                "another nonlinearity at this loop than its valve: a limit or saturation, an "
                "on/off or split-range element, a process nonlinearity, or a nonlinear "
                "disturbance entering here")
    return (f"its own window says {src.verdict} and its cycle is "
            f"{'linear' if src.nli is not None else 'not shown nonlinear'}: the evidence "
            "points to its tuning (a controller gain near the loop's limit) or a disturbance "
            "entering at this loop, not to its valve")


def group_reason(period_s: float, loops: int, ranking: tuple[MemberEvidence, ...],
                 indicators: tuple[IndicatorEvidence, ...], d: Decision) -> str:
    """The group's reason: the source and what named it, or where the cycle enters, and the
    called loops that follow or are kept."""
    top = ranking[0]
    what = f"the {period_s:.0f} s cycle shared by {loops} loops"
    by_name = {i.name: i for i in indicators}
    if d.source is not None:
        src = next(e for e in ranking if e.loop == d.source)
        reason = f"{d.source} is the source of {what}, named by {', '.join(d.named_by)}: " \
                 f"{src.note()}"
        if src.verdict == Verdict.NO_STICTION.value:
            reason += f"; {instead(src)}"
        if d.upstream is not None:
            reason += (f"; also fed from outside? indicator {d.upstream} leads the cycle "
                       f"({_ind(by_name[d.upstream])}), not strongly enough to outweigh "
                       f"{d.source}'s own evidence: check upstream")
    elif d.outside is not None:
        reason = (f"{what} enters from outside the loops: indicator {d.outside} leads them "
                  f"({_ind(by_name[d.outside])}) and no loop shows stronger evidence of its "
                  f"own (best loop candidate {top.loop}: {top.note()})")
    else:
        reason = (f"no loop analysed here shows evidence of being the source of {what} (best "
                  f"candidate {top.loop}: {top.note()}): its source is not among the loops "
                  "read, or cannot be told from this data")
    over = [f"{loop}: {why}" for loop, why in d.demoted.items()]
    if over:
        reason += "; followers its own tests called stiction: " + "; ".join(over)
    if d.kept:
        by_why: dict[str, list[str]] = {}
        for loop, why in d.kept.items():
            by_why.setdefault(why, []).append(loop)
        reason += "; called stiction by its own tests and kept: " + "; ".join(
            f"{', '.join(loops_)}: {why}" for why, loops_ in by_why.items())
    return reason


def propagated(g: Group, name: str, a: Assessment) -> Assessment:
    """``a`` (a follower's ``stiction``) as ``propagated``, the reason naming why."""
    if g.source is not None:
        where = f"its source is {g.source} (named by {', '.join(g.named_by)})"
    elif g.entry is not None:
        where = f"it enters from outside the loops (indicator {g.entry} leads it)"
    else:
        where = "no loop analysed here shows evidence of being its source"
    why = g.demoted.get(name)
    return dataclasses.replace(
        a, verdict=Verdict.PROPAGATED, fd=None, fs=None, jump=None, fd_op=None, fs_op=None,
        cycles_used=0, multi_jump=False,
        reason=f"propagated: the cycle of {g.period_s:.0f} s is shared by {len(g.loops)} "
               f"loops and {where}" + (f"; {why}" if why else "")
               + f"; this loop's own tests said stiction at {a.confidence or 0.0:.2f}")


def kept(g: Group, name: str, a: Assessment) -> Assessment:
    """``a`` (a called loop the plant view keeps as it is) with the group in its reason."""
    return dataclasses.replace(
        a, reason=f"{a.reason}; plant view: shares the cycle of {g.period_s:.0f} s of group "
                  f"{g.number}: {g.kept[name]}")
