"""Hysteresis of the plant view: a changed story is published only once it has held.

Each round gives, per time base, a new plant assessment. Its *story* is what an engineer
acts on: each group's loops, source, other sources and entry, and each loop's role and
source (:func:`story`). A new assessment with the story in force replaces it at once (its
periods and reasons are this round's). One whose story differs is put in force only when
that same new story has come ``rounds`` rounds in a row; until then the one in force stays
(its roles still decide which verdicts become ``propagated``), and the round counts as held
back. So a weak member that joins a group every other round, or a source that the evidence
names one round and not the next, changes nothing that is published; a change that lasts
is published ``rounds - 1`` rounds late. The first assessment of a time base is put in
force at once (there is nothing to hold).

Together with the analysis' own hysteresis (a source named stays while its evidence stands
at a lower bar, :mod:`stiction.plant.decide`) this is the documented rule of
docs/configuration.md (``plant.hold_rounds``); the changes published and the rounds held
back are counted (``stiction_plant_changes_total``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Hashable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the analysis only in the worker
    from stiction.plant import PlantAssessment

__all__ = ["WINDOW_SHARE", "Hold", "story"]

WINDOW_SHARE = 0.125
"""Share of the window's span a changed story must last (an eighth: at the gateway's
defaults, 300 s rounds on two-hour windows, three rounds)."""


def story(pa: PlantAssessment) -> frozenset[Any]:
    """What a plant assessment tells an engineer: per group its loops, source, other
    sources and entry; per loop in a group its role and source."""
    groups = frozenset((frozenset(g.loops), g.source, frozenset(g.also_sources), g.entry)
                       for g in pa.groups)
    roles = frozenset((n, r.role, r.source) for n, r in pa.roles.items() if r.role)
    return frozenset({("groups", groups), ("roles", roles)})


@dataclasses.dataclass
class _Pending:
    story: frozenset[Any]
    rounds: int
    since: float | None  # process time of the newest sample when it was first seen


class Hold:
    """The assessment in force per time base (module doc)."""

    def __init__(self, rounds: int) -> None:
        if rounds < 1:
            raise ValueError(f"rounds must be at least 1, was {rounds}")
        self.rounds = rounds
        self.in_force: dict[Hashable, PlantAssessment] = {}
        self._pending: dict[Hashable, _Pending] = {}
        self.held = 0  # rounds a changed story was held back, in all

    def settle(self, key: Hashable, pa: PlantAssessment, *, newest: float | None = None,
               span: float = 0.0) -> PlantAssessment:
        """The assessment in force for time base ``key`` after this round's ``pa``;
        ``newest``: the process time of the round's newest sample, ``span``: the window's
        span, s (without them, rounds alone count)."""
        now = self.in_force.get(key)
        new = story(pa)
        if now is None or story(now) == new:
            self._pending.pop(key, None)
            self.in_force[key] = pa
            return pa
        pending = self._pending.get(key)
        if pending is None or pending.story != new:
            pending = _Pending(new, 0, newest)
        pending.rounds += 1
        lasted = newest is None or pending.since is None or \
            newest - pending.since >= WINDOW_SHARE * span
        if pending.rounds >= self.rounds and lasted:
            self._pending.pop(key, None)
            self.in_force[key] = pa
            return pa
        self._pending[key] = pending
        self.held += 1
        return now

    def keep_only(self, keys: set[Hashable]) -> None:
        """Forget the time bases not analysed this round (their loops are gone)."""
        for key in set(self.in_force) - keys:
            del self.in_force[key]
            self._pending.pop(key, None)
