"""The evidence gate: a window is called ``stiction`` only where evidence about the valve says
so (issue 35).

The learned decision (:mod:`.model`) reads every test's numbers, not only its vote, and can
reach a high confidence from numbers that sit where, in its corpus, sticky valves were: a good
valve under a 5-minute load exported at 1 minute read ``stiction`` 0.91 while bicoherence,
Horch and the fast-cycle test voted *not* stiction and the rest could not tell; 12 plant
records of one tag read 0.87-0.98 while every test said "cannot tell" (the one event in them a
setpoint step). An engineer cannot check such a call against anything. So, whatever the
confidence, a call of ``stiction`` needs a source of evidence that says stiction, and
:func:`unbacked` says when none does:

1. **A vote for stiction.** At least one source votes +1. The sources are the registered
   tests (:mod:`stiction.detectors.registry`) by name, and any later source of its own vote
   (a learned shape score) joins the mapping under its own name: the gate is the same.
2. **A cycle whose shape can be seen.** On a cycle of fewer than
   :data:`~stiction.signal.oscillation.MIN_PERIOD` samples the triangle and square shapes,
   stuck intervals and OP-PV patterns the other tests read are gone; only the sources made
   for such a cycle (:data:`FAST_READERS`: the fast-cycle test, Thornhill & Hägglund 1997)
   can back the call. A window that fails either rule is at most ``undetermined``; its
   reason says which rule and keeps the confidence the decision gave.

It is pure: votes in, a phrase or None out. :func:`stiction.analyze` applies it after the
learned decision; ``tests/stiction/diagnosis/test_gate.py`` holds the property over the
shared cases, the plant records, the Tennessee Eastman runs and simulated windows. Measured
on ``bench real_data`` (issue 35): it withdraws 12 of the 13 calls of plant tag 2411FIC20102
(sticky records called 19 -> 7 of 35, sticky tags 4 -> 3 of 7; none of the 45 others called
before or after; with the records' setpoint read, :mod:`.setpoint`, 13 of 35), none of the
Tennessee Eastman calls (each backed by a test, the fast cycles of IDV 14 by the fast-cycle
test), and of the 252 realistic simulations one sticky and one triangle-load call (process
unknown; none with it given); ``bench false_alarms`` unchanged (3 of 540 windows, each
backed by the shape tests).
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["FAST_READERS", "unbacked"]

FAST_READERS = frozenset({"fast_cycle"})
"""The sources that read a cycle too fast for its shape (rule 2 of the module doc)."""


def unbacked(votes: Mapping[str, int], *, too_fast: bool) -> str | None:
    """Why the ``votes`` (source name -> +1 stiction, 0 cannot tell, -1 not stiction) do not
    back a call of stiction (module doc), as a phrase; None when they do. ``too_fast``: the
    window's cycle is too fast to see its shape."""
    against = sorted(name for name, v in votes.items() if v < 0)
    if too_fast:
        backing = sorted(name for name, v in votes.items() if v > 0 and name in FAST_READERS)
        if not backing:
            only = ", ".join(sorted(FAST_READERS))
            return f"no test made for a cycle this fast ({only}) says stiction"
        return None
    if any(v > 0 for v in votes.values()):
        return None
    if against:
        return f"no test says stiction ({', '.join(against)} say not stiction)"
    return "no test says stiction (every test cannot tell)"
