"""Verdict hysteresis: a published verdict changes when the evidence has changed, not when
the window slides by one round.

In SCADA each verdict change is an alarm, and alarm management (ISA-18.2, EEMUA 191) treats
a chattering alarm as a defect: the demo's sticky level loop went ``stiction ->
undetermined -> stiction -> undetermined -> stiction`` in 90 s while nothing in its valve or
load changed, its confidence hovering about the decision's threshold (issue 32). So each
loop's verdict passes :meth:`VerdictFilter.publish` before it is published (per loop, every
analysis round, before the plant step; ``verdict_hysteresis`` in the config,
docs/configuration.md):

- **Judgements** (:data:`FILTERED`: ``stiction``, ``no_stiction``, ``undetermined``,
  ``not_oscillating``, ``valve_not_responding``): a new one replaces the published one when
  the loop's verdict has differed from it for ``rounds`` analysis rounds in a row (the
  latest is published), or, out of ``stiction`` (the alarm), at once when its confidence
  of stiction fell from the published one's by at least ``margin``: evidence that moved
  that far is a change (a valve repaired), not a window sliding (into ``stiction`` a new
  verdict always holds its rounds: :meth:`VerdictFilter._moved`); both confidences of one
  kind (both from the valve's travel, or both from OP and PV). Between the other
  judgements the rounds alone decide: a weakly cycling loop's confidence can jump by half
  the scale from one round to the next (the demo plant's FIC102: 0.05, 0.63, 0.06), and
  nothing urgent hangs on those changes.
  A round whose confidence lies within ``band`` of one of the decision's thresholds
  (:meth:`VerdictFilter._near_threshold`) neither counts towards a change nor resets one:
  it could have read the other way (the demo's U2.TIC201 read 0.507 against a threshold of
  0.5 on one machine, which restarted a change that then came once its window was full).
  Until then the published judgement stays, its reason saying what this round found and
  how long it has held. Either way the published numbers are those of the published
  verdict (a size only beside ``stiction``).
- **Warming up after a judgement** (the window restarted after an outage, or the gateway
  after a restart, and holds too little to judge: ``gateway/core/jobs.py``): the judgement
  is kept, its reason saying it is held, since when and what the loop waits for, until the
  loop is judged again (issue 31), but not longer than the loop's window after the round
  that judged it (``max_hold_s``; issue 35 item 5: restarts faster than a window fills kept
  a verdict for ever, each restart's first round saying it was judged then). The round
  that judged it survives restarts (the state file keeps it) and is published with the
  result (:meth:`VerdictFilter.published`: a register of the extended block, a metric).
- Everything else is published at once: a loop's first verdict, ``warming_up`` before any
  judgement, ``bad_data`` (a data fault is said at once, and so is its end: the first
  judgement after it).

``rounds: 1`` turns the hysteresis off. Counted (:attr:`VerdictFilter.counts`, the metric
``stiction_verdict_changes_total{outcome}``): changes published (``published``) and rounds in
which a change was held back, warming up included (``held_back``). The time of a held result
is its round's, as every result's: the age of the latest assessment stays the analysis's;
the age of the judgement it shows is :meth:`VerdictFilter.published`'s.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Iterable

from stiction import Assessment, Verdict
from stiction.diagnosis.travel import BY_TRAVEL

from ..config.model import HysteresisSettings

__all__ = ["FILTERED", "HELD_BACK", "HELD_WARMING", "NOT_HELD", "OUTCOMES", "VerdictFilter",
           "by_travel"]

FILTERED = frozenset({Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                      Verdict.NOT_OSCILLATING, Verdict.VALVE_NOT_RESPONDING})
"""The verdicts that judge a loop (module doc); the others pass at once."""
READ_FROM_CONFIDENCE = frozenset({Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                                  Verdict.NOT_OSCILLATING})
"""The judgements whose line to the next is a threshold of the confidence."""
OUTCOMES = ("published", "held_back")
HELD, HELD_END = "held", ". "
"""How a held result's reason begins, and the end of that head (no head holds ". ")."""


NOT_HELD, HELD_BACK, HELD_WARMING = 0, 1, 2
"""How a published result came to be (register +22 of the extended block, the metric
``stiction_loop_verdict_hold``): this round's judgement; a judgement held back while a new
one waits for its rounds; a judgement held through warming up."""


@dataclasses.dataclass
class _Loop:
    judged: Assessment  # the published judgement, as analysed
    at: float  # the round that last judged so (wall Unix seconds)
    away: int = 0  # rounds in a row whose verdict differed from it
    held_since: float | None = None  # the first warming-up round it was held through
    hold: int = NOT_HELD  # what the last round published


class VerdictFilter:
    """Per loop (by name, so a reload keeps it), what was published; see the module doc.
    ``on_count`` hears each outcome counted (the metric)."""

    def __init__(self, settings: HysteresisSettings | None = None, *,
                 on_count: Callable[[str], None] | None = None) -> None:
        self.settings = settings or HysteresisSettings()
        self.on_count = on_count
        self._loops: dict[str, _Loop] = {}
        self.counts = dict.fromkeys(OUTCOMES, 0)

    def _count(self, outcome: str) -> None:
        self.counts[outcome] += 1
        if self.on_count is not None:
            self.on_count(outcome)

    def publish(self, loop: str, new: Assessment, t: float, *,
                shown: Assessment | None = None, shown_at: float | None = None,
                max_hold_s: float | None = None) -> Assessment:
        """What to publish for ``loop`` this round, given its analysis ``new`` (at wall
        time ``t``); ``shown``: what the loop shows now where this filter has not seen it
        yet (a result restored from the state file or kept over a reload), judged at
        ``shown_at`` (default ``t``); ``max_hold_s``: the longest a judgement is held
        through warming up, counted from the round that judged it (the loop's window:
        after that no sample it was judged on is left), after which ``new`` is published.
        :meth:`published` says when what it returns was judged, and whether it is held."""
        state = self._loops.get(loop)
        if state is None and shown is not None and shown.verdict in FILTERED:
            state = self._loops[loop] = _Loop(_unheld(shown), t if shown_at is None
                                              else shown_at)
        if new.verdict not in FILTERED:
            if new.verdict == Verdict.WARMING_UP and state is not None:
                if max_hold_s is None or t - state.at <= max_hold_s:
                    return self._hold_warming(state, new, t)
                self._loops.pop(loop)  # held too long: its valve may have changed since
                self._count("published")
                return _prefixed(new, (
                    f"no longer held: {state.judged.verdict} was judged {_clock(state.at)}, "
                    f"longer ago than the loop's window ({max_hold_s:.0f} s)"))
            self._loops.pop(loop, None)  # nothing judged to keep
            return new
        near = self._near_threshold(new)
        if state is None or state.judged.verdict == new.verdict:
            # at its threshold it could have read the other way: a change in the making
            # keeps its rounds
            self._loops[loop] = _Loop(new, t, state.away if state and near is not None else 0)
            return new
        state.held_since = None
        if near is None:
            state.away += 1
        if state.away >= self.settings.rounds or self._moved(state.judged, new):
            self._loops[loop] = _Loop(new, t)
            self._count("published")
            return new
        self._count("held_back")
        state.hold = HELD_BACK
        moves = (f" or its confidence moves {self.settings.margin:g} from "
                 f"{state.judged.confidence:.2f}" if state.judged.confidence is not None and
                 new.confidence is not None and
                 Verdict.STICTION in (state.judged.verdict, new.verdict) else "")
        at = "" if near is None else (f", within {self.settings.band:g} of the decision's "
                                        f"threshold {near:g}: not counted")
        return _prefixed(state.judged, (
            f"held: this round says {new.verdict}{_conf(new)}{at}, published when it holds "
            f"{self.settings.rounds} rounds ({state.away} so far){moves}"))

    def _near_threshold(self, a: Assessment) -> float | None:
        """The threshold (the decision's or the shape network's, :func:`thresholds`) that the
        confidence of ``a`` lies within ``band`` of, where its judgement is read from the
        confidence; else None. Such a round could have read the other way on another
        machine or with one sample more: it neither counts towards a change nor resets
        one."""
        if a.confidence is None or a.verdict not in READ_FROM_CONFIDENCE or \
                self.settings.rounds == 1:  # rounds 1: every round's verdict is published
            return None
        return next((th for th in thresholds()
                     if abs(a.confidence - th) < self.settings.band), None)

    def _moved(self, old: Assessment, new: Assessment) -> bool:
        """Out of ``stiction`` (the alarm), with the confidence moved by the margin: a valve
        repaired. Into it a new verdict always holds its rounds: with the shape network the
        confidence of one window can leap (the demo's U2.FIC101: 0.33, 0.89, 0.26 in three
        rounds, each leap past the margin), and a call that stands for one round sends a
        crew to a valve for nothing (issue 36). Only confidences of one kind
        compare: the valve's travel gives the share of its reversals that stuck, OP and PV
        a probability, and a loop whose position is usable in some rounds and not in others
        flipped between the two every round (issue 35)."""
        return (old.verdict == Verdict.STICTION != new.verdict and
                old.confidence is not None and new.confidence is not None and
                by_travel(old) == by_travel(new) and
                abs(new.confidence - old.confidence) >= self.settings.margin)

    def published(self, loop: str, t: float) -> tuple[float, int]:
        """``(judged, hold)`` of what :meth:`publish` returned for ``loop`` at ``t``: the
        wall time of the round that judged its verdict (``t``: this one) and
        :data:`NOT_HELD`, :data:`HELD_BACK` or :data:`HELD_WARMING`."""
        state = self._loops.get(loop)
        return (t, NOT_HELD) if state is None else (state.at, state.hold)

    def _hold_warming(self, state: _Loop, new: Assessment, t: float) -> Assessment:
        state.away = 0
        state.hold = HELD_WARMING
        if state.held_since is None:
            state.held_since = t
        self._count("held_back")
        return _prefixed(state.judged, (
            f"held since {_clock(state.held_since)}, last judged {_clock(state.at)}: "
            f"{new.reason}"))

    def keep(self, loops: Iterable[str]) -> None:
        """Forget loops no longer configured (after a reload)."""
        names = set(loops)
        for name in [n for n in self._loops if n not in names]:
            del self._loops[name]


def by_travel(a: Assessment) -> bool:
    """Whether the valve's travel decided ``a`` (its evidence ``travel`` says so)."""
    return any(e.test == "travel" and e.note.startswith(BY_TRAVEL) for e in a.evidence)


def _prefixed(a: Assessment, head: str) -> Assessment:
    return dataclasses.replace(a, reason=f"{head}{HELD_END}{a.reason}")


def _unheld(a: Assessment) -> Assessment:
    """``a`` without the head a held result's reason starts with (a result restored from
    the state file may be one): what was judged."""
    if a.reason.startswith(HELD) and HELD_END in a.reason:
        return dataclasses.replace(a, reason=a.reason.split(HELD_END, 1)[1])
    return a


def _conf(a: Assessment) -> str:
    return "" if a.confidence is None else f" (confidence {a.confidence:.2f})"


def _clock(t: float) -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(t))


@functools.cache
def thresholds() -> tuple[float, ...]:
    """Every threshold a verdict is read from its confidence at: the learned decision's
    (``no_stiction`` up to 0.5, ``stiction`` from 0.87) and the OP-PV shape network's
    (``no_stiction`` under 0.16, ``stiction`` from 0.69; issue 36), which is the confidence
    where the network reads the window. Imported at the first judgement, not at start (the
    network's module pulls SciPy's signal package into the polling process:
    :func:`gateway.core.siteshare.warm` reads them at start, before polling)."""
    from stiction.diagnosis.call import shipped  # noqa: PLC0415

    t = shipped()
    return (t.no_stiction_at, t.stiction_at, t.band_low, t.threshold)
