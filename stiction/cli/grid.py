"""Rows of a historian export on a regular time grid, for ``stiction analyze`` and
``stiction plant``; every message shows the time stamps as the file wrote them."""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ._common import UsageError
from .cells import Cells
from .decimals import is_number

__all__ = ["JITTER", "OFF_GRID", "SKIPPED_HOUR", "Stamps", "grid", "on_grid", "spring_forward"]

JITTER = 0.25  # a time stamp further than this share of the sample time off the grid is off it
OFF_GRID = 0.01  # share of rows that may be off the grid before the stamps are refused


@dataclasses.dataclass(frozen=True)
class Stamps:
    """A time column read: seconds (Unix seconds for date-times), and the cells as the file
    wrote them with their line numbers, for messages."""

    seconds: np.ndarray
    written: Sequence[str] | Cells
    lines: Sequence[int] | np.ndarray
    zone: dt.tzinfo | None = None
    """The zone to show date-times in; None when the column holds seconds."""
    notes: tuple[str, ...] = ()
    appended: tuple[int, ...] = ()
    """Lines where the header repeats (two exports appended)."""
    naive: bool = False
    """Date-times that name no zone, read as UTC without ``--tz``: maybe local times."""

    def text(self, i: int) -> str:
        """Row ``i``'s stamp as the file wrote it."""
        return self.written[i].strip()

    def at(self, i: int) -> str:
        return f"{self.text(i)!r} (line {self.lines[i]})"


def on_grid(path: Path, name: str, t: np.ndarray | Stamps, op: np.ndarray, pv: np.ndarray
            ) -> tuple[float, np.ndarray, np.ndarray, list[str]]:
    """OP and PV on a regular grid of the median sample time (:func:`grid`)."""
    ts, (grid_op, grid_pv), notes = grid(path, name, t, (op, pv))
    return ts, grid_op, grid_pv, notes


def grid(path: Path, name: str, t: np.ndarray | Stamps, series: Sequence[np.ndarray]
         ) -> tuple[float, list[np.ndarray], list[str]]:
    """Put the rows on a regular grid of the median sample time: repeated time stamps keep
    their last row, missing rows become gaps (NaN), as a historian export needs. Stamps
    more than a quarter sample off the grid in over 1 % of the rows are refused (the
    historian exported recorded, compressed values, not samples at a fixed interval)."""
    stamps = t if isinstance(t, Stamps) else Stamps(
        t, [f"{x:g}" for x in t], list(range(2, t.size + 2)))
    t = stamps.seconds
    steps = np.diff(t)
    back = np.flatnonzero(steps < 0)
    if back.size:
        raise UsageError(_backwards(path, name, stamps, int(back[0])))
    steps = steps[steps > 0]
    if steps.size == 0:
        raise UsageError(f"{path}: column {name!r} holds one time only "
                         f"({stamps.text(0)!r}); give --ts S")
    ts = float(np.median(steps))
    shortest, longest = float(steps.min()), float(steps.max())
    del steps
    k = np.round((t - t[0]) / ts).astype(np.int64)
    if k[-1] + 1 > 50 * t.size:
        raise UsageError(f"{path}: time stamps too irregular to put on a grid of {ts:g} s")
    off = np.abs(t - t[0] - k * ts)
    n_off = int(np.count_nonzero(off > JITTER * ts))
    if n_off > OFF_GRID * t.size:
        first = int(np.flatnonzero(off > JITTER * ts)[0])
        raise UsageError(
            f"{path}: time stamps irregular: {n_off} of {t.size} rows more than a quarter of "
            f"the {ts:g} s sample time off its grid (the first {stamps.at(first)}; steps "
            f"{shortest:g} to {longest:g} s): the historian exported recorded "
            "(compressed) values; export interpolated values at a fixed interval, or give "
            "--ts S if the rows are equally spaced")
    out = []
    for x in series:
        g = np.full(int(k[-1]) + 1, np.nan)
        g[k] = x  # a repeated index keeps the last row
        out.append(g)
    distinct = 1 + int(np.count_nonzero(np.diff(k)))  # k never goes back (refused above)
    repeated = t.size - distinct
    missing = int(k[-1]) + 1 - distinct
    notes = list(stamps.notes)
    if float(off.max()) > 0.02 * ts:
        notes.append(f"time stamps jitter up to {float(off.max()):.3g} s around the {ts:g} s "
                     "grid: each row put on the nearest grid point")
    if repeated:
        notes.append(f"{repeated} rows repeat a time stamp (on a {ts:g} s grid): the last "
                     "of each kept")
    if missing:
        notes.append(f"{missing} samples missing from the {ts:g} s time grid: treated as gaps")
    del k, off
    skipped = spring_forward(stamps, ts)
    return ts, out, notes + ([skipped] if skipped else [])


SKIPPED_HOUR = "the time stamps skip an hour"
"""How :func:`spring_forward`'s note begins."""


def spring_forward(stamps: Stamps, ts: float) -> str | None:
    """The note for date-times that name no zone and skip exactly an hour, from a whole
    hour between midnight and 03:00 (the start of summer time in local stamps: read as UTC
    without ``--tz``, the hour is a gap of that length), or None."""
    if not stamps.naive or stamps.seconds.size < 2:
        return None
    t = stamps.seconds
    tol = max(JITTER * ts, 1.0)
    hits = np.flatnonzero(np.abs(np.diff(t) - (ts + 3600.0)) <= tol)  # an hour missing
    gone = (t[hits] + ts) % 86_400.0  # the wall clock of the first stamp missing
    at_hour = np.abs((gone + ts / 2) % 3600.0 - ts / 2) <= tol
    hits = hits[at_hour & (gone < 3 * 3600.0 + ts)]
    if hits.size == 0:
        return None
    i = int(hits[0])
    return (f"{SKIPPED_HOUR} from {stamps.at(i)} to {stamps.at(i + 1)}: the start of summer "
            "time in local time stamps? Give --tz with the historian's zone (e.g. --tz "
            "Europe/Berlin): the hour is then no gap")


def _backwards(path: Path, name: str, stamps: Stamps, i: int) -> str:
    """Time goes back from row ``i`` to the next: the two stamps as written, and the likely
    cause: two exports appended, the end of summer time in local stamps, or unsorted rows."""
    head = (f"{path}: time goes backwards in column {name!r}: {stamps.at(i)} -> "
            f"{stamps.at(i + 1)}")
    joined = [a for a in stamps.appended if stamps.lines[i] < a < stamps.lines[i + 1]]
    if joined:
        return (f"{head}, where the header repeats at line {joined[0]}: two exports appended "
                "that overlap in time; remove the overlap, or export the whole stretch at once")
    hour = 3000 <= stamps.seconds[i] - stamps.seconds[i + 1] <= 3700
    if stamps.zone is not None and hour and not is_number(stamps.text(i)):  # local times
        return (f"{head}: an hour back, the end of summer time in local time stamps? Give "
                "--tz with the historian's zone (e.g. --tz Europe/Berlin), or export in UTC "
                "or with the zone")
    return (f"{head}: sort the rows by time; a daylight-saving change in local time? Export "
            "in UTC or with the zone, or give --tz")
