"""The plant-wide step of an analysis round: windows in, groups and roles out (no IO).

After each round the loops whose windows share a time base (the same poll interval and the
same window length: the same span of process time, sample for sample) are analysed
together by :func:`stiction.plant.analyze_plant` (docs/architecture.md):

1. :func:`plant_jobs` copies the windows of every such set of loops into one
   :class:`PlantJob`: samples that are not GOOD as NaN (gaps), aligned at the newest sample
   (devices polled at one interval are read within one interval of each other), averaged
   down to at most ``max_samples`` samples.
2. :func:`analyze_plant_job` is the worker's entry (picklable in, picklable out).
3. :class:`PlantTracker` numbers the groups of all jobs for the outputs: a group keeps its
   number from round to round while it shares loops with the one before (new groups take the
   lowest free number, so numbers stay small: the Modbus register holds 1-255), and says
   when a group appears, changes its source or ends (one log line each).
What the store holds, :class:`.plantview.PlantView` (the groups and, per loop, its group
number and role), is a module of its own: the store imports it, this module imports the
windows, and the windows the store, so nothing imports in a circle.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment

from .plantview import MAX_GROUP_NUMBER, PlantGroup, PlantView
from .points import Quality
from .windows import LoopGroup

if TYPE_CHECKING:  # the analysis only in the worker (it brings in scipy.signal, ~0.5 s)
    from stiction.plant import PlantAssessment

__all__ = ["CHUNK", "PlantJob", "PlantTracker", "analyze_plant_job", "plant_jobs"]

CHUNK = 512  # loops copied out of a bank at once (bounds the copies' memory)


@dataclasses.dataclass(frozen=True)
class PlantJob:
    """The loops of one poll interval, for a worker: ``op``/``pv`` (loops x samples,
    float32, NaN: gap) at ``ts`` (the poll interval times the averaging factor)."""

    rows: tuple[int, ...]  # the loops' rows in the result store
    names: tuple[str, ...]
    op: NDArray[np.float32]
    pv: NDArray[np.float32]
    ts: float
    assessments: Mapping[str, Assessment]
    processes: Mapping[str, str]


def _averaged(x: NDArray[np.float32], factor: int) -> NDArray[np.float32]:
    """Rows of ``x`` averaged over blocks of ``factor`` samples (the oldest samples that
    fill no whole block are dropped; a block with a gap is a gap)."""
    if factor == 1:
        return x
    n = x.shape[1] // factor * factor
    return np.asarray(x[:, x.shape[1] - n:].reshape(x.shape[0], -1, factor).mean(axis=2),
                      dtype=np.float32)


def plant_jobs(groups: Sequence[LoopGroup], assessments: Mapping[int, Assessment], *,
               max_samples: int) -> list[PlantJob]:
    """One job per time base (poll interval, window length) with at least two loops
    assessed (``assessments``: store row -> this round's assessment), in that order."""
    by_base: dict[tuple[float, int], list[LoopGroup]] = {}
    for g in groups:
        if g.bank.count > 0 and any(int(r) in assessments for r in g.rows):
            by_base.setdefault((g.ts, g.bank.size), []).append(g)
    jobs = []
    for ts, length in sorted(by_base):
        members = by_base[ts, length]
        factor = max(1, math.ceil(length / max_samples))
        width = length // factor
        rows: list[int] = []
        names: list[str] = []
        ops: list[NDArray[np.float32]] = []
        pvs: list[NDArray[np.float32]] = []
        processes: dict[str, str] = {}
        for g in members:
            cols = [c for c in range(len(g.configs)) if int(g.rows[c]) in assessments]
            for lo in range(0, len(cols), CHUNK):
                part = np.asarray(cols[lo:lo + CHUNK], dtype=np.intp)
                _t, op, pv, q = g.bank.series(part)
                n = min(op.shape[1], length)
                o = np.full((len(part), length), np.nan, dtype=np.float32)
                p = np.full((len(part), length), np.nan, dtype=np.float32)
                o[:, length - n:] = op[:, op.shape[1] - n:]
                p[:, length - n:] = pv[:, pv.shape[1] - n:]
                bad = np.ones((len(part), length), dtype=bool)
                bad[:, length - n:] = q[:, q.shape[1] - n:] != Quality.GOOD
                o[bad] = np.nan
                p[bad] = np.nan
                ops.append(_averaged(o, factor))
                pvs.append(_averaged(p, factor))
                for c in part.tolist():
                    cfg = g.configs[c]
                    rows.append(int(g.rows[c]))
                    names.append(cfg.name)
                    processes[cfg.name] = cfg.process
        if len(rows) < 2:
            continue
        jobs.append(PlantJob(
            tuple(rows), tuple(names),
            np.concatenate(ops) if ops else np.zeros((0, width), np.float32),
            np.concatenate(pvs) if pvs else np.zeros((0, width), np.float32),
            ts * factor, {nm: assessments[r] for r, nm in zip(rows, names, strict=True)},
            processes))
    return jobs


def analyze_plant_job(job: PlantJob) -> PlantAssessment:
    """Worker entry: the plant analysis of one job."""
    from stiction.plant import analyze_plant  # noqa: PLC0415  (see the imports)

    loops = {name: (job.op[k], job.pv[k]) for k, name in enumerate(job.names)}
    return analyze_plant(loops, ts=job.ts, assessments=job.assessments,
                         processes=job.processes)


class PlantTracker:
    """Numbers the groups of successive rounds and tells what changed (see the module)."""

    def __init__(self) -> None:
        self.groups: dict[int, PlantGroup] = {}

    def update(self, found: Sequence[tuple[PlantAssessment, Sequence[str]]]
               ) -> tuple[PlantView, list[str]]:
        """``found``: each job's plant assessment (with the job's loop names). Returns the
        new view and the log lines of what changed."""
        new = [(g.period_s, g.source, g.loops, g.reason, pa)
               for pa, _names in found for g in pa.groups]
        new.sort(key=lambda x: (-len(x[2]), x[0]))  # big groups choose their number first
        free = dict(self.groups)
        out: list[PlantGroup] = []
        events: list[str] = []
        taken: set[int] = set()
        for period, source, loops, reason, _pa in new:
            members = set(loops)
            best = max(free.values(), key=lambda g: (len(members & set(g.loops)), -g.number),
                       default=None)
            if best is not None and members & set(best.loops):
                number = best.number
                del free[number]
                if best.source != source:
                    events.append(f"plant group {number}: source {_src(source)} (was "
                                  f"{_src(best.source)}), period {period:.0f} s, "
                                  f"{len(loops)} loops")
            else:
                number = next(k for k in range(1, len(self.groups) + len(new) + 2)
                              if k not in self.groups and k not in taken)
                events.append(f"plant group {number} appeared: period {period:.0f} s, "
                              f"source {_src(source)}, {len(loops)} loops: "
                              f"{_listed(loops)}")
            taken.add(number)
            out.append(PlantGroup(number, period, source, tuple(loops), reason))
        for g in sorted(free.values(), key=lambda g: g.number):
            events.append(f"plant group {g.number} ended (period {g.period_s:.0f} s, source "
                          f"{_src(g.source)}, {len(g.loops)} loops)")
        out = [g for g in out if g.number <= MAX_GROUP_NUMBER]
        out.sort(key=lambda g: g.number)
        self.groups = {g.number: g for g in out}
        roles: dict[str, tuple[int, str]] = {}
        by_key = {(g.period_s, g.loops): g.number for g in out}
        for pa, _names in found:
            for name, role in pa.roles.items():
                if role.group is None or role.role is None:
                    continue
                sg = pa.group(role.group)
                found_number = by_key.get((sg.period_s, sg.loops))
                if found_number is not None:
                    roles[name] = (found_number, role.role)
        return PlantView(tuple(out), roles), events


def _src(source: str | None) -> str:
    return "none among the loops (from outside)" if source is None else source


def _listed(loops: Sequence[str], most: int = 8) -> str:
    shown = ", ".join(loops[:most])
    return shown + (f" and {len(loops) - most} more" if len(loops) > most else "")
