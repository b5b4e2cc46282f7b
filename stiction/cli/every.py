"""``stiction analyze --every DURATION``: a long export judged a window at a time, one
verdict per window, a table over time, as a trend-minded engineer reads a week: per day, or
per shift (``--every 8h``).

Windows are aligned to the clock: to midnight of the first sample's day in the file's zone
(its time stamps' zone, or ``--tz``; rows numbered by ``--ts`` or given in seconds count from
0), then every DURATION on. A window at either end shorter than half of DURATION (the file
starts at 06:00, ``--every 1d``) is left out, said so; a file shorter than one window is one
window. Each window is analysed as ``stiction analyze --from FROM --to TO`` would analyse it
alone (``from`` and ``to``: its first and last samples' stamps, as the file writes them)."""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import itertools
import re
from pathlib import Path

import numpy as np

from .loop import Analysed, Loaded, LoopOptions, judge, load

__all__ = ["UNITS", "Window", "duration", "every", "windows"]

UNITS = {"s": 1.0, "sec": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0, "d": 86_400.0,
         "w": 604_800.0}
_DURATION = re.compile(r"(\d+(?:\.\d+)?)\s*([a-z]*)")


def duration(text: str) -> float:
    """``--every``'s value in seconds: a number and a unit (``8h``, ``1d``, ``30min``,
    ``90s``, ``1w``; several add: ``1h30min``), or seconds."""
    parts = _DURATION.findall(text.strip().lower())
    joined = "".join(f"{n}{u}" for n, u in parts)
    if not parts or joined != re.sub(r"\s+", "", text.strip().lower()) or \
            any(u not in UNITS and u for _, u in parts):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a duration: give a number and a unit, e.g. 8h, 1d, 30min, 90s")
    seconds = sum(float(n) * UNITS[u or "s"] for n, u in parts)
    if not seconds > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: a duration longer than 0")
    return seconds


@dataclasses.dataclass(frozen=True)
class Window:
    """One window of ``--every``: its first and last samples' stamps as the file writes
    them, and its analysis."""

    start: str
    stop: str
    analysed: Analysed


def windows(got: Loaded, length: float) -> tuple[list[tuple[int, int]], list[str]]:
    """The windows' sample ranges ``[a, b)`` of a file read, aligned to the clock, and the
    notes on the ends left out."""
    ts, n = got.ts, got.size
    t0 = float(got.clock.t[0]) + got.first * ts  # the first sample's time
    zone = None if got.stamps is None else got.stamps.zone
    offset = 0.0
    if zone is not None:
        at = dt.datetime.fromtimestamp(t0, dt.UTC)
        offset = (zone.utcoffset(at.replace(tzinfo=None)) or dt.timedelta(0)).total_seconds()
    slot = np.floor((t0 + offset + np.arange(n) * ts) / length).astype(np.int64)
    cuts = [0, *(np.flatnonzero(np.diff(slot)) + 1).tolist(), n]
    spans = list(itertools.pairwise(cuts))
    notes = []
    half = 0.5 * length / ts
    if len(spans) > 1:
        for end, (a, b) in (("first", spans[0]), ("last", spans[-1])):
            if b - a < half:
                notes.append(f"the {end} {_said((b - a) * ts)} ({_text(got, a)!r} to "
                             f"{_text(got, b - 1)!r}): less than half a window: not analysed")
        kept = [s for k, s in enumerate(spans)
                if not (k in (0, len(spans) - 1) and s[1] - s[0] < half)]
        if kept:  # else every window is short: each is analysed as it is
            return kept, notes
    return spans, []


def _text(got: Loaded, k: int) -> str:
    """Sample ``k`` (of those read) as the file writes its time."""
    return got.clock.text(got.first + k)


def _said(seconds: float) -> str:
    for unit, size in (("d", 86_400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def every(path: Path, o: LoopOptions, length: float) -> tuple[list[Window], list[str]]:
    """The file read once and judged a window at a time (:func:`windows`); the reading's
    notes and the windows left out, once."""
    got = load(path, o)
    spans, notes = windows(got, length)
    return ([Window(_text(got, a), _text(got, b - 1), judge(got, o, a, b))
             for a, b in spans], [*got.notes, *notes])
