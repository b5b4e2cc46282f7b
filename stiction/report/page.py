"""What a report holds: the list worst first and, per suspect valve, what the crew needs at the
maintenance meeting. Filled by the gateway's ``stiction-gateway report`` (from its verdict
history, state file and findings) and by ``stiction analyze --report`` (from a unit's exports);
rendered by :func:`stiction.report.html.render`. Every text here may come from a file (a tag
name, a crew's note): the renderer escapes all of it."""

from __future__ import annotations

import dataclasses

from .._assessment import Sizes
from .._validate import FloatArray

__all__ = ["SECTION_VERDICTS", "Finding", "Listed", "Report", "Trend", "next_step"]

SECTION_VERDICTS = ("stiction", "valve_not_responding", "undetermined")
"""The verdicts whose valves get a section of their own (the suspects)."""


@dataclasses.dataclass(frozen=True)
class Trend:
    """The window that decided: ``t`` seconds from ``start`` (a time as the source writes
    it), OP and PV with their units."""

    t: FloatArray
    op: FloatArray
    pv: FloatArray
    start: str = ""
    op_unit: str = "% of span"
    pv_unit: str = "PV units"


@dataclasses.dataclass(frozen=True)
class Finding:
    """One finding of the crew, as its ledger writes it."""

    date: str
    finding: str
    fd: float | None = None
    fs: float | None = None
    by: str = ""
    note: str = ""
    step_test: str = ""  # the step test's figures where the row gives them


@dataclasses.dataclass(frozen=True)
class Listed:
    """One loop of the list, with what its section shows.

    ``history``: (date, verdict) in time order, each a change; ``role``: its plant-wide
    role in words ("" in no group); ``travel``: what the valve's measured travel said
    (position read), "" without; ``calibration``: which calibration the confidence is
    from."""

    name: str
    rank: int | None
    score: float | None
    verdict: str
    confidence: float | None = None
    reason: str = ""
    sizes: Sizes | None = None
    since: str = ""
    role: str = ""
    findings: tuple[Finding, ...] = ()
    history: tuple[tuple[str, str], ...] = ()
    trend: Trend | None = None
    travel: str = ""
    calibration: str = "shipped"
    error: str = ""
    source: str = ""  # where its samples came from (offline: the file), "" to say nothing

    @property
    def suspect(self) -> bool:
        return self.verdict in SECTION_VERDICTS


@dataclasses.dataclass(frozen=True)
class Report:
    """A whole report: ``loops`` worst first; ``sections``: how many suspects get a section
    (the first ones of the list); ``notes``: lines under the title (the period, the site's
    calibration, what was read)."""

    title: str
    loops: tuple[Listed, ...]
    notes: tuple[str, ...] = ()
    sections: int = 25
    generated: str = ""


_NEXT = {
    "stiction": "Confirm with a valve test in manual: OP steps of 0.5-1 % of span; a sticky "
                "valve does not move until the steps add up to about fs. Then plan its "
                "maintenance (packing, actuator, positioner), the largest fd or slip first; "
                "until then, less integral action slows the cycle.",
    "valve_not_responding": "Check now: OP moves and PV does not follow, the loop is not "
                            "controlling (valve stuck or isolated, positioner, air supply, a "
                            "bypass open).",
    "undetermined": "Do not act on the verdict alone: watch the next rounds (the confidence "
                    "says which way it leans), look at the OP-PV plot, and test the valve "
                    "with small OP steps in manual when the process allows.",
    "no_stiction": "The cycle looks like tuning or a disturbance: look at the tuning and at "
                   "loops upstream cycling at the same period. This does not clear the "
                   "valve.",
    "propagated": "Fix the source of the cycle first (its plant-wide role names it); this "
                  "loop only carries it.",
}


def next_step(loop: Listed) -> str:
    """What to do next for a loop: by its verdict, and by the crew's latest finding where
    it says more."""
    text = _NEXT.get(loop.verdict, "Nothing to do about the valve now.")
    latest = loop.findings[-1] if loop.findings else None
    if latest is not None and latest.finding == "stiction" and loop.verdict == "stiction":
        text = (f"The crew found it sticking on {latest.date}: plan the repair. After it, the "
                "verdict should leave stiction within a window.")
    elif latest is not None and latest.finding == "ok" and loop.verdict == "stiction":
        text += (f" The crew found the valve fine on {latest.date}: look for another cause "
                 "(the load, the tuning) before testing it again.")
    return text
