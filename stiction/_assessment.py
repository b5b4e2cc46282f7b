"""The one result type: :class:`Assessment`.

Every output of the product (the CLI's JSON, the gateway's Modbus registers, its
Prometheus metrics and its state file) is a view of an ``Assessment``; nothing else
carries a result.
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Any

__all__ = ["Assessment", "Evidence", "Verdict"]


class Verdict(enum.StrEnum):
    """What the analysis concluded about one window of one loop.

    ``WARMING_UP`` is never returned by :func:`stiction.analyze`: the gateway gives it to a
    window that is still filling where the analysis found no oscillation (a slower one may
    not have enough cycles in it yet), instead of a ``NOT_OSCILLATING`` that sounds final.
    """

    STICTION = "stiction"
    NO_STICTION = "no_stiction"
    UNDETERMINED = "undetermined"
    NOT_OSCILLATING = "not_oscillating"
    BAD_DATA = "bad_data"
    VALVE_NOT_RESPONDING = "valve_not_responding"
    WARMING_UP = "warming_up"


@dataclasses.dataclass(frozen=True, slots=True)
class Evidence:
    """What one detection test saw in one window.

    ``test`` is a short stable name (``"si_op"``, ``"bicoherence"``, ...); ``value`` the
    test's headline statistic (None when the test could not run on this window); ``vote``
    +1 when the test says stiction, -1 when it says not stiction and 0 when it cannot tell;
    ``note`` one phrase a plant engineer can read ("OP half cycles fit a triangle").
    """

    test: str
    value: float | None
    vote: int
    note: str

    def to_dict(self) -> dict[str, Any]:
        return {"test": self.test, "value": self.value, "vote": self.vote, "note": self.note}


@dataclasses.dataclass(frozen=True, slots=True)
class Assessment:
    """The verdict on one window of OP/PV, and the stiction size when it applies.

    Valve quantities (``fd``, ``fs``, ``jump``) are fractions of the valve span, as in
    He & Wang (2014) Table 2; ``fd_op`` and ``fs_op`` are the same in OP units (for
    ``op_range=(0, 100)``, percent). Fields that were not estimated are ``None``.
    """

    verdict: Verdict
    reason: str
    oscillating: bool = False
    period_s: float | None = None
    stiction_index: float | None = None
    fd: float | None = None
    fs: float | None = None
    jump: float | None = None
    fd_op: float | None = None
    fs_op: float | None = None
    cycles_used: int = 0
    multi_jump: bool = False
    warnings: tuple[str, ...] = ()
    confidence: float | None = None
    evidence: tuple[Evidence, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping with exactly the field names of the dataclass."""
        out = dataclasses.asdict(self)
        out["verdict"] = str(self.verdict)
        out["warnings"] = list(self.warnings)
        out["evidence"] = [e.to_dict() for e in self.evidence]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Assessment:
        """Inverse of :meth:`to_dict`; unknown keys are an error."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown Assessment fields: {sorted(unknown)}")
        kwargs = dict(data)
        kwargs["verdict"] = Verdict(kwargs["verdict"])
        kwargs["warnings"] = tuple(kwargs.get("warnings", ()))
        kwargs["evidence"] = tuple(Evidence(**e) for e in kwargs.get("evidence", ()))
        return cls(**kwargs)
