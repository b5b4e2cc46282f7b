"""One loop's file analysed: how it is read (:class:`LoopOptions`), what ``stiction analyze``
shows of it (:func:`analyze_file`, :func:`view`), for one file and for a batch
(:mod:`.batch`) alike.

Besides the assessment it holds what weighed most in the decision (the learned decision's
parts, which are not votes: :mod:`stiction.diagnosis.reasons`) and, where the window cycles
only in bursts, the stretch that cycles (:mod:`stiction.diagnosis.stretch`) in the file's own
time, with the ``--from``/``--to`` that analyse it alone."""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._assessment import Assessment, Verdict
from ..diagnosis.analyze import Details, analyze_details
from ..diagnosis.stretch import Stretch, regular_stretch
from . import decimals, historian
from ._common import UsageError
from .grid import SKIPPED_HOUR
from .memory import affordable, readable
from .plot import Clock, window_clock

__all__ = ["SP_COLUMNS", "Analysed", "FileTime", "Loaded", "LoopOptions", "analyze_file", "bursts",
           "judge", "load", "rejudged", "view"]

SP_COLUMNS = ("sp", "setpoint", "set point", "set_point")
"""Column names read as the setpoint when ``--sp`` is not given (any case), in this order."""


@dataclasses.dataclass(frozen=True)
class LoopOptions:
    """How one file is read and analysed: the command line's options (:meth:`from_args`),
    or a manifest row's cells over them (:mod:`.batch`). Every per-file option is a field
    here, so that a new one flows through the command line and the manifest alike."""

    op: str = "op"
    pv: str = "pv"
    position: str | None = None  # the valve's position column (OP units): the travel decides
    sp: str | None = None  # the setpoint column (None: the first of SP_COLUMNS the file has)
    no_sp: bool = False  # read no setpoint column
    time: str | None = None
    ts: float | None = None
    kp: float | None = None
    delay: float = 0.0
    process: str = "self-regulating"
    op_range: tuple[float, float] | None = None
    start: str | None = None  # --from
    stop: str | None = None  # --to
    decimal: str | None = None
    tz: dt.tzinfo | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> LoopOptions:
        """The options ``stiction analyze`` was given (every field's namesake in ``args``)."""
        got = {f.name: getattr(args, f.name) for f in dataclasses.fields(cls)}
        if got["op_range"] is not None:
            got["op_range"] = (float(got["op_range"][0]), float(got["op_range"][1]))
        return cls(**got)


@dataclasses.dataclass(frozen=True)
class Analysed:
    """One file analysed: ``shown`` what ``--json`` prints (:func:`view`), the assessment
    with the file's notes among its warnings, the details for a plot, the sample time, the
    OP range and the plot's clock (the file's own time)."""

    shown: dict[str, Any]
    assessment: Assessment
    details: Details
    ts: float
    op_range: tuple[float, float] | None
    clock: Clock


@dataclasses.dataclass(frozen=True)
class Loaded:
    """One file read as ``o`` says: its samples on the grid between ``--from`` and ``--to``
    (``first``: the grid index of the first), the sample time, the file's time, the notes."""

    op: np.ndarray
    pv: np.ndarray
    position: np.ndarray | None
    sp: np.ndarray | None
    ts: float
    first: int
    clock: FileTime
    stamps: historian.Stamps | None
    notes: list[str]

    @property
    def size(self) -> int:
        return int(self.op.size)


def load(path: Path, o: LoopOptions) -> Loaded:
    """Read ``path`` as ``o`` says (:mod:`.historian`); unusable input raises
    :class:`~stiction.cli._common.UsageError` naming it."""
    wanted = [(o.op, "--op"), (o.pv, "--pv")]
    if o.position is not None:
        wanted.append((o.position, "--position"))
    sp_names: list[str] = []

    def select(header: list[str]) -> list[int]:
        sp_names.extend(n for n in [_sp_column(header, o)] if n is not None)
        return historian.needed(header, path, wanted + [(n, "--sp") for n in sp_names],
                                o.time, o.ts)

    readable(path)
    table = historian.read_table(path, decimal=o.decimal, tz=o.tz, select=select)
    if not sp_names:  # a long export, turned wide: its columns are its tags
        sp_names += [n for n in [_sp_column(table.header, o)] if n is not None]
    sp_name = sp_names[0] if sp_names else None
    if sp_name is not None:
        wanted.append((sp_name, "--sp"))
    got = historian.read_signals(table, wanted, o.time, o.ts, o.op_range)
    table = got.table  # oldest first
    op, pv = got.series[0], got.series[1]
    pos = got.series[2] if o.position is not None else None
    sp = got.series[-1] if sp_name is not None else None
    ts, t = got.ts, got.stamps
    secs = np.arange(table.size) * ts if t is None else t.seconds
    clock = FileTime(table, got.t_col, secs, ts)
    first, op, pv = clock.cut(o, op, pv)
    pos = None if pos is None else pos[first:first + op.size]
    sp = None if sp is None else sp[first:first + op.size]
    return Loaded(op, pv, pos, sp, ts, first, clock, t, got.notes)


def analyze_file(path: Path, o: LoopOptions) -> Analysed:
    """Read ``path`` as ``o`` says (:func:`load`) and analyse its window (:func:`judge`); a
    bad option value raises :class:`~stiction.ParameterError`."""
    return judge(load(path, o), o)


def judge(got: Loaded, o: LoopOptions, a: int = 0, b: int | None = None) -> Analysed:
    """The samples ``a`` to ``b`` (default: all) of a file read (:func:`load`) analysed,
    once their analysis fits in memory (:func:`.memory.affordable`)."""
    b = got.size if b is None else b
    affordable(b - a, got.ts, got.clock.table.path)
    op, pv, ts, t = got.op[a:b], got.pv[a:b], got.ts, got.stamps
    pos = None if got.position is None else got.position[a:b]
    sp = None if got.sp is None else got.sp[a:b]
    d = analyze_details(op, pv, ts=ts, kp=o.kp, delay=o.delay, process=o.process,
                        op_range=o.op_range, position=pos, sp=sp)
    first = got.first + a
    # the plot's axis, the file's time: the samples judged (after a leading gap, SP steps)
    shown_from = window_clock(t, ts, op, pv)
    if d.op is not None:
        shown_from = Clock((0.0 if t is None else float(t.seconds[0])) + d.start * ts,
                           shown_from.zone)
    shown_from = dataclasses.replace(shown_from, start=shown_from.start + first * ts)
    notes = got.notes
    a_ = dataclasses.replace(d.assessment, warnings=(*notes, *d.assessment.warnings))
    skipped = next((n for n in notes if n.startswith(SKIPPED_HOUR)), None)
    if skipped is not None and a_.verdict == Verdict.BAD_DATA:  # the gap is the clock's
        a_ = dataclasses.replace(a_, reason=f"{a_.reason} ({skipped.split(': ')[0]}: local "
                                 "time without --tz? See the warning)")
    stretch = bursts(d)
    if stretch is not None:
        a_ = dataclasses.replace(a_, reason=a_.reason + stretch.reason(ts))
    shown = view(a_, d, got.clock.stretch(stretch, first + d.start) if stretch else None)
    return Analysed(shown, a_, d, ts, o.op_range, shown_from)


def _sp_column(header: list[str], o: LoopOptions) -> str | None:
    """The setpoint column to read: ``--sp``'s, else the first of :data:`SP_COLUMNS` the
    header has (any case), unless ``--no-sp``; None: no setpoint."""
    if o.no_sp:
        return None
    if o.sp is not None:
        return o.sp
    folded = [h.casefold() for h in header]
    return next((header[folded.index(n)] for n in SP_COLUMNS if n in folded), None)


def bursts(d: Details) -> Stretch | None:
    """The stretch that cycles, where the window's verdict rests on a cycle it found
    irregular (:func:`~stiction.diagnosis.stretch.regular_stretch`), and the stretch is a
    real part of the window; else None."""
    if d.op is None or d.pv is None or d.cycle is None or d.cycle.regular or \
            d.assessment.verdict not in BURST_VERDICTS:
        return None
    st = regular_stretch(d.op, d.pv)
    if st is None or st.stop - st.start > PART * d.op.size:
        return None
    return st


BURST_VERDICTS = (Verdict.STICTION, Verdict.NO_STICTION, Verdict.UNDETERMINED,
                  Verdict.NOT_OSCILLATING)
PART = 0.8
"""A stretch longer than this share of the window is the window: no hint."""


@dataclasses.dataclass(frozen=True)
class FileTime:
    """The file's own time for the samples: ``t`` (seconds) per row, ``ts`` the grid's
    sample time; the time column ``col`` of ``table`` (None: rows every ``ts`` from 0)."""

    table: historian.Table
    col: int | None
    t: np.ndarray
    ts: float

    def seconds(self, text: str, option: str) -> float:
        """``--from``/``--to``'s value in the file's seconds."""
        if self.col is None:
            try:
                return float(text)
            except ValueError:
                raise UsageError(f"{option} {text!r}: with --ts give seconds from the first "
                                 "row") from None
        evidence: dict[str, int] = {}
        decimals.tally_text(text, 0, evidence)
        one = dataclasses.replace(self.table, columns={self.col: historian.Cells.of([text])},
                                  lines=np.zeros(1, dtype=np.int64),
                                  evidence={self.col: evidence}, memo={})
        try:
            return float(historian.times(one, self.col).seconds[0])
        except UsageError:
            raise UsageError(f"{option} {text!r}: not a time as the file writes them "
                             f"(e.g. {self.text(0)!r})") from None

    def cut(self, o: LoopOptions, op: np.ndarray, pv: np.ndarray
            ) -> tuple[int, np.ndarray, np.ndarray]:
        """The samples between ``--from`` and ``--to`` (index of the first, op, pv)."""
        if o.start is None and o.stop is None:
            return 0, op, pv
        grid = self.t[0] + np.arange(op.size) * self.ts
        lo = -np.inf if o.start is None else self.seconds(o.start, "--from")
        hi = np.inf if o.stop is None else self.seconds(o.stop, "--to")
        keep = np.flatnonzero((grid >= lo - self.ts / 4) & (grid <= hi + self.ts / 4))
        if keep.size < 2:
            raise UsageError(f"--from/--to: {keep.size} samples between them (the file runs "
                             f"from {self.text(0)!r} to {self.text(op.size - 1)!r})")
        return int(keep[0]), op[keep[0] : keep[-1] + 1], pv[keep[0] : keep[-1] + 1]

    def text(self, k: int) -> str:
        """Sample ``k``'s time as the file wrote it (the nearest row's stamp)."""
        at = self.t[0] + k * self.ts
        if self.col is None:
            return f"{at:g}"
        i = int(np.argmin(np.abs(self.t - at)))
        return self.table.cell(i, self.col)

    def stretch(self, st: Stretch, first: int) -> dict[str, Any]:
        """The stretch in the file's time (``first``: the window's first sample)."""
        return {"from": self.text(first + st.start), "to": self.text(first + st.stop - 1),
                "source": st.source, "period_s": st.period * self.ts,
                "regularity": st.regularity}


SIZE_FIELDS = ("fd", "fs", "jump", "fd_op", "fs_op", "cycles_used", "band", "band_op")


def view(a: Assessment, d: Details | None = None, stretch: dict[str, Any] | None = None
         ) -> dict[str, Any]:
    """What ``analyze`` prints: the assessment's fields with the sizes in one unit under
    ``size`` (:meth:`stiction.Assessment.sizes`: unit, fd, fs, jump and, when read from
    the limit cycle, cycles_used; None when not sized) instead of fractions beside OP
    units; ``weighed``: what weighed in the decision, strongest first (``d.parts``: each
    entry's part of the log-odds, + for stiction; not votes); ``stretch``: the stretch to
    analyse alone, in the file's time, or None; ``site``: ``"none"`` (scored alone, at the
    simulation's share of sticky valves) or ``"adapted"`` (at ``site_share``, the batch's)."""
    out = {k: v for k, v in a.to_dict().items() if k not in SIZE_FIELDS}
    out["site"], out["site_share"] = a.site, a.site_share  # "none": scored alone (issue 36)
    sizes = a.sizes()
    out["size"] = None if sizes is None else sizes.to_dict()
    parts = {} if d is None or d.parts is None else d.parts
    out["weighed"] = dict(sorted(parts.items(), key=lambda kv: -abs(kv[1])))
    out["stretch"] = stretch
    return out


def rejudged(rows: Sequence[Any], judge: Callable[[Assessment], Assessment]) -> list[Any]:
    """A batch's rows (:class:`.report.Row`) with each analysed file's assessment judged
    again by ``judge`` (the unit's calibration, the site's share) and what ``--json`` shows
    of it redone (:func:`view`); a row not analysed stays as it is."""
    out = []
    for row in rows:
        got = row.analysed
        if got is None:
            out.append(row)
            continue
        a = judge(got.assessment)
        got = dataclasses.replace(got, assessment=a,
                                  shown=view(a, got.details, got.shown.get("stretch")))
        out.append(dataclasses.replace(row, shown=got.shown, analysed=got))
    return out
