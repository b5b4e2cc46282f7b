"""The plant view as the result store and the outputs see it (no IO, no analysis).

:class:`PlantView` holds the groups (:class:`PlantGroup`, numbered stably by
:class:`gateway.core.plant.PlantTracker`) and, per loop in one, its group number and role.
It imports nothing of the gateway's core, so the store can hold it and the plant step
(:mod:`gateway.core.plant`, which reads the windows) can build it without an import circle.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

__all__ = ["CHANGES", "MAX_GROUP_NUMBER", "ROLE_CODES", "PlantGroup", "PlantView"]

ROLE_CODES = {"": 0, "source": 1, "follower": 2}
"""A loop's role as a number (Modbus register +18, high byte): 0 in no group."""
MAX_GROUP_NUMBER = 255  # the register's low byte
CHANGES = ("group_appeared", "group_ended", "source", "role", "held")
"""What :attr:`PlantView.changes` counts: published changes of each kind (a loop's role
counts when it becomes or stops being a source or a follower), and ``held``: rounds a
changed view was held back (:mod:`gateway.core.planthold`)."""


@dataclasses.dataclass(frozen=True)
class PlantGroup:
    """One group as the outputs see it: its ``number`` (stable while it lasts), period,
    source loop (None: no loop analysed is the source) and member loops."""

    number: int
    period_s: float
    source: str | None
    loops: tuple[str, ...]
    reason: str = ""
    entry: str | None = None  # the indicator the cycle enters by from outside (no source)


@dataclasses.dataclass(frozen=True)
class PlantView:
    """The groups, per loop in one its (group number, role), and the changes counted
    since the gateway started (:data:`CHANGES`)."""

    groups: tuple[PlantGroup, ...] = ()
    roles: Mapping[str, tuple[int, str]] = dataclasses.field(default_factory=dict)
    changes: Mapping[str, int] = dataclasses.field(default_factory=dict)

    def of(self, loop: str) -> tuple[int, str, str | None]:
        """(group number, role, source) of ``loop``; (0, "", None) when in no group."""
        number, role = self.roles.get(loop, (0, ""))
        if number == 0:
            return 0, "", None
        return number, role, self.group(number).source

    def group(self, number: int) -> PlantGroup:
        return self._by_number[number]

    @property
    def _by_number(self) -> dict[int, PlantGroup]:
        cache: dict[int, PlantGroup] | None = self.__dict__.get("_cache")
        if cache is None:
            cache = {g.number: g for g in self.groups}
            object.__setattr__(self, "_cache", cache)
        return cache
