"""The one result type: :class:`Assessment`.

Every output of the product (the CLI's JSON, the gateway's Modbus registers, its
Prometheus metrics and its state file) is a view of an ``Assessment``; nothing else
carries a result.
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Any

__all__ = ["ADVICE", "DEFAULT_K", "POSITION_USES", "Assessment", "Evidence", "Sizes", "Verdict"]

DEFAULT_K = 1.99
"""He's overshoot factor K that :func:`stiction.analyze` assumes unless told (Table 1 valve)."""


class Verdict(enum.StrEnum):
    """What the analysis concluded about one window of one loop.

    ``WARMING_UP`` is never returned by :func:`stiction.analyze`: the gateway gives it to a
    window that is still filling where the analysis found no oscillation (a slower one may
    not have enough cycles in it yet), instead of a ``NOT_OSCILLATING`` that sounds final.
    ``PROPAGATED`` is never returned by it either: the plant view (:mod:`stiction.plant`)
    gives it to a loop that carries a cycle it shares with others, whose source is another
    loop or outside the loops analysed.
    """

    STICTION = "stiction"
    NO_STICTION = "no_stiction"
    UNDETERMINED = "undetermined"
    NOT_OSCILLATING = "not_oscillating"
    BAD_DATA = "bad_data"
    VALVE_NOT_RESPONDING = "valve_not_responding"
    WARMING_UP = "warming_up"
    PROPAGATED = "propagated"

    @property
    def advice(self) -> str:
        """What the verdict means and asks of the engineer, in one sentence: the one text
        every output prints (``stiction analyze``, the demo's table) and
        docs/modbus-map.md#verdict-codes says at length. It holds to what the analysis was
        measured to be worth (docs/accuracy.md): ``stiction`` is usually right, and no other
        verdict clears the valve (most sticky valves on real plants were not called)."""
        return ADVICE[self]


ADVICE: dict[Verdict, str] = {
    Verdict.STICTION: "the valve sticks: confirm with small OP steps in manual; plan its "
                      "maintenance, the largest fd first",
    Verdict.NO_STICTION: "no test found stiction in this window; this does not clear the "
                         "valve (most sticky valves on real plants are not called): look at "
                         "the tuning and at loops cycling at the same period, and test the "
                         "valve when the process allows",
    Verdict.UNDETERMINED: "it cycles, the evidence is unclear: do not act on it alone, nor "
                          "clear the valve; watch the next rounds, test the valve when you "
                          "can",
    Verdict.NOT_OSCILLATING: "it does not cycle in this window: nothing to do about a cycle; "
                             "this does not clear the valve (a sticky valve shows only once "
                             "it cycles)",
    Verdict.BAD_DATA: "the window cannot be analysed: the reason says why (gaps, frozen, "
                      "saturated)",
    Verdict.VALVE_NOT_RESPONDING: "OP moves, PV does not: check the valve, its positioner "
                                  "and air now",
    Verdict.WARMING_UP: "the loop's window is still filling: wait (fill says how far)",
    Verdict.PROPAGATED: "its cycle comes from the group's source loop: fix that one first; "
                        "judge this valve again once the cycle has gone",
}
"""Each verdict's :attr:`Verdict.advice`."""


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


POSITION_USES = ("used", "could_not_tell", "not_a_position")
"""What became of the valve's position where one was given (:attr:`Assessment.position_use`):
it was used (its travel decided the verdict, or agreed with a calm loop's); it could not tell
(too gappy, too few reversals: OP and PV decided); it did not show it is the valve's
position (moves against OP, another scale, a lag, held while PV moved: OP and PV decided,
and the reason says why)."""

SITE_NONE = "none"
""":attr:`Assessment.site` of a window scored alone, at the simulation's share of sticky valves."""
SPAN = "% of span"
OP_UNITS = "OP units"


@dataclasses.dataclass(frozen=True, slots=True)
class Sizes:
    """A sticky valve's size in one unit, as every output shows it (the CLI, its JSON, the
    Modbus registers; the Prometheus series hold the same percentages / 100, as ``_ratio``).

    ``unit`` is ``"% of span"`` when the OP range was known, else ``"OP units"``; ``fd``,
    ``fs`` (None without kp) and ``jump`` (the valve's slip J = K (fs - fd), He & Wang 2014
    eq 7; None without fs) are in it. ``cycles_used`` is the number of limit cycles whose
    jumps were read, None when the size came from another method (the valve fitted to PV,
    the OP-PV ellipse: the reason names it). ``band`` (dead band plus stick band, S of
    Choudhury's model) is set only where the size was measured from the valve's travel
    (:mod:`stiction.quantify.travel`); the JSON then shows it with ``slip`` (= ``jump``).
    """

    unit: str
    fd: float
    fs: float | None
    jump: float | None
    cycles_used: int | None
    band: float | None = None

    @property
    def slip(self) -> float | None:
        """The valve's jump when it breaks free (J): ``jump``, named as the travel reads it."""
        return self.jump

    @property
    def of_span(self) -> bool:
        """In % of the valve span (else OP units)."""
        return self.unit == SPAN

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"unit": self.unit, "fd": self.fd, "fs": self.fs,
                               "jump": self.jump}
        if self.cycles_used is not None:
            out["cycles_used"] = self.cycles_used
        if self.band is not None:
            out["band"] = self.band
            out["slip"] = self.slip
        return out


@dataclasses.dataclass(frozen=True, slots=True)
class Assessment:
    """The verdict on one window of OP/PV, and the stiction size when it applies.

    Valve quantities (``fd``, ``fs``, ``jump``) are fractions of the valve span, as in
    He & Wang (2014) Table 2; ``fd_op`` and ``fs_op`` are the same in OP units (for
    ``op_range=(0, 100)``, percent). Fields that were not estimated are ``None``. What
    the outputs show is :meth:`sizes`: one unit, labelled, the jump wherever fd and fs are.
    ``band`` / ``band_op`` (dead band plus stick band, fraction of span / OP units) are set
    only where the valve's position was read and the size measured from its travel.
    ``position_use`` is None where no position was given, else one of
    :data:`POSITION_USES` (the evidence ``travel`` says why); :meth:`to_dict` leaves it out
    while it is None, so that a reader older than the field reads what has no position.
    ``site`` says how the OP-PV shape network's probability was read (issue 36): ``"none"``
    (one window alone, at the simulation's share of sticky valves: "scored without site
    adaptation") or ``"adapted"`` (moved to the share of sticky valves the windows of a
    site imply, ``site_share``: :mod:`stiction.diagnosis.adapt`); :meth:`to_dict` leaves
    both out while the site is ``"none"``.
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
    band: float | None = None
    band_op: float | None = None
    position_use: str | None = None
    site: str = SITE_NONE
    site_share: float | None = None

    def sizes(self, k: float = DEFAULT_K) -> Sizes | None:
        """The size in one unit (:class:`Sizes`): percent of span when the OP range was
        given, OP units otherwise; None when the valve was not sized. A jump the sizing did
        not give itself (the valve fitted to PV gives fd and fs) is K (fs - fd), the
        relation the limit cycle's sizing holds to; ``k`` is the K the analysis used."""
        if self.fd is not None:
            unit, scale, fd, fs, band = SPAN, 100.0, self.fd, self.fs, self.band
        elif self.fd_op is not None:
            unit, scale, fd, fs, band = OP_UNITS, 1.0, self.fd_op, self.fs_op, self.band_op
        else:
            return None
        jump = self.jump if unit == SPAN else None
        if jump is None and fs is not None:
            jump = k * (fs - fd)
        return Sizes(unit, fd * scale, None if fs is None else fs * scale,
                     None if jump is None else jump * scale,
                     self.cycles_used if self.cycles_used > 0 else None,
                     None if band is None else band * scale)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping with exactly the field names of the dataclass (``position_use``
        only where a position was given, ``site`` and ``site_share`` only where the site was
        adapted)."""
        out = dataclasses.asdict(self)
        if self.position_use is None:
            del out["position_use"]
        if self.site == SITE_NONE and self.site_share is None:  # as a reader before them
            del out["site"], out["site_share"]
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
