"""The plant-wide step of an analysis round: windows in, groups and roles out (no IO).

After each round the loops whose windows share a time base (the same poll interval and the
same window length: the same span of process time, sample for sample) are analysed
together by :func:`stiction.plant.analyze_plant` (docs/architecture.md):

1. :func:`plant_jobs` copies the windows of every such set of loops into one
   :class:`PlantJob`: samples that are not GOOD as NaN (gaps), aligned at the newest sample
   (devices polled at one interval are read within one interval of each other), averaged
   down to at most ``max_samples`` samples.
   Each loop's ``unit`` goes with it: groups form within a unit.
2. :func:`analyze_plant_job` is the worker's entry (picklable in, picklable out). The job
   carries the plant view in force for its time base, so a source named before stays while
   its evidence stands (:mod:`stiction.plant.decide`).
3. :class:`PlantTracker` holds each time base's view in force: a new view whose story
   differs (a group appears or ends, a group's source or a loop's role changes) is put in
   force only once it has held for ``hold_rounds`` rounds in a row
   (:mod:`.planthold`); then it numbers the groups of all jobs for the outputs: a group
   keeps its number from round to round while it shares loops with the one before (new
   groups take the lowest free number, so numbers stay small: the Modbus register holds
   1-255), says when a group appears, changes its source or ends (one log line each) and
   counts the changes published and the rounds a change was held back.
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

from .planthold import Hold
from .plantview import CHANGES, MAX_GROUP_NUMBER, PlantGroup, PlantView
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
    units: Mapping[str, str] = dataclasses.field(default_factory=dict)  # loop -> its unit
    key: tuple[float, int] = (0.0, 0)  # the time base: poll interval, window length
    previous: PlantAssessment | None = None  # the view in force for this time base
    newest: float | None = None  # process time of the newest sample in the windows


def _averaged(x: NDArray[np.float32], factor: int) -> NDArray[np.float32]:
    """Rows of ``x`` averaged over blocks of ``factor`` samples (the oldest samples that
    fill no whole block are dropped): the mean of a block's good samples, a gap (NaN) when
    fewer than half of them are good (a lone missed poll does not blank its block)."""
    if factor == 1:
        return x
    n = x.shape[1] // factor * factor
    blocks = x[:, x.shape[1] - n:].reshape(x.shape[0], -1, factor)
    good = np.isfinite(blocks)
    count = good.sum(axis=2)
    total = np.where(good, blocks, 0.0).sum(axis=2, dtype=np.float64)
    mean = np.divide(total, count, out=np.full(count.shape, np.nan), where=2 * count >= factor)
    return np.asarray(mean, dtype=np.float32)


def plant_jobs(groups: Sequence[LoopGroup], assessments: Mapping[int, Assessment], *,
               max_samples: int,
               previous: Mapping[tuple[float, int], PlantAssessment] | None = None
               ) -> list[PlantJob]:
    """One job per time base (poll interval, window length) with at least two loops
    assessed (``assessments``: store row -> this round's assessment), in that order;
    ``previous``: the view in force per time base."""
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
        units: dict[str, str] = {}
        newest = max((float(g.bank.t[(g.bank.head - 1) % g.bank.size]) for g in members),
                     default=None)
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
                    if cfg.unit:
                        units[cfg.name] = cfg.unit
        if len(rows) < 2:
            continue
        jobs.append(PlantJob(
            tuple(rows), tuple(names),
            np.concatenate(ops) if ops else np.zeros((0, width), np.float32),
            np.concatenate(pvs) if pvs else np.zeros((0, width), np.float32),
            ts * factor, {nm: assessments[r] for r, nm in zip(rows, names, strict=True)},
            processes, units, (ts, length), (previous or {}).get((ts, length)), newest))
    return jobs


def analyze_plant_job(job: PlantJob) -> PlantAssessment:
    """Worker entry: the plant analysis of one job."""
    from stiction.plant import analyze_plant  # noqa: PLC0415  (see the imports)

    loops = {name: (job.op[k], job.pv[k]) for k, name in enumerate(job.names)}
    return analyze_plant(loops, ts=job.ts, assessments=job.assessments,
                         processes=job.processes, units=job.units, previous=job.previous)


class PlantTracker:
    """Holds each time base's view in force, numbers the groups of successive rounds, tells
    and counts what changed (see the module)."""

    def __init__(self, hold_rounds: int = 1) -> None:
        self.groups: dict[int, PlantGroup] = {}
        self.hold = Hold(hold_rounds)
        self.changes: dict[str, int] = dict.fromkeys(CHANGES, 0)
        self._roles: Mapping[str, tuple[int, str]] = {}

    @property
    def in_force(self) -> dict[tuple[float, int], PlantAssessment]:
        """The plant assessment in force per time base (the jobs' ``previous``)."""
        return self.hold.in_force  # type: ignore[return-value]

    def round(self, jobs: Sequence[PlantJob], found: Sequence[PlantAssessment]
              ) -> tuple[dict[int, Assessment], PlantView, list[str]]:
        """A round's plant step after the workers: each job's new assessment (``found``)
        settled against the one in force, the in-force ones applied to the job's
        assessments (store row -> the plant-aware assessment of each loop it changed), the
        new view and its log lines."""
        in_force = [self.hold.settle(job.key, pa, newest=job.newest,
                                     span=job.key[0] * job.key[1])
                    for job, pa in zip(jobs, found, strict=True)]
        self.hold.keep_only({job.key for job in jobs})
        applied: dict[int, Assessment] = {}
        for job, pa in zip(jobs, in_force, strict=True):
            changed = pa.apply(job.assessments)
            for row, name in zip(job.rows, job.names, strict=True):
                if changed[name] is not job.assessments[name]:
                    applied[row] = changed[name]
        view, events = self.update([(pa, job.names) for job, pa in zip(jobs, in_force,
                                                                       strict=True)])
        return applied, view, events

    def update(self, found: Sequence[tuple[PlantAssessment, Sequence[str]]]
               ) -> tuple[PlantView, list[str]]:
        """``found``: each job's plant assessment in force (with the job's loop names).
        Returns the new view and the log lines of what changed."""
        new = [(g.period_s, g.source, g.loops, g.reason, g.entry)
               for pa, _names in found for g in pa.groups]
        new.sort(key=lambda x: (-len(x[2]), x[0]))  # big groups choose their number first
        free = dict(self.groups)
        out: list[PlantGroup] = []
        events: list[str] = []
        taken: set[int] = set()
        for period, source, loops, reason, entry in new:
            members = set(loops)
            best = max(free.values(), key=lambda g: (len(members & set(g.loops)), -g.number),
                       default=None)
            if best is not None and members & set(best.loops):
                number = best.number
                del free[number]
                if best.source != source:
                    self.changes["source"] += 1
                    events.append(f"plant group {number}: source {_src(source, entry)} (was "
                                  f"{_src(best.source, best.entry)}), period {period:.0f} s, "
                                  f"{len(loops)} loops")
            else:
                number = next(k for k in range(1, len(self.groups) + len(new) + 2)
                              if k not in self.groups and k not in taken)
                self.changes["group_appeared"] += 1
                events.append(f"plant group {number} appeared: period {period:.0f} s, "
                              f"source {_src(source, entry)}, {len(loops)} loops: "
                              f"{_listed(loops)}")
            taken.add(number)
            out.append(PlantGroup(number, period, source, tuple(loops), reason, entry))
        for g in sorted(free.values(), key=lambda g: g.number):
            self.changes["group_ended"] += 1
            events.append(f"plant group {g.number} ended (period {g.period_s:.0f} s, source "
                          f"{_src(g.source, g.entry)}, {len(g.loops)} loops)")
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
        self.changes["role"] += sum(1 for n in set(roles) | set(self._roles)
                                    if _role(self._roles, n) != _role(roles, n))
        self._roles = roles
        self.changes["held"] = self.hold.held
        return PlantView(tuple(out), roles, dict(self.changes)), events


def _role(roles: Mapping[str, tuple[int, str]], name: str) -> str:
    return roles.get(name, (0, ""))[1]


def _src(source: str | None, entry: str | None = None) -> str:
    if source is not None:
        return source
    return f"none among the loops (enters by {entry})" if entry else "none among the loops"


def _listed(loops: Sequence[str], most: int = 8) -> str:
    shown = ", ".join(loops[:most])
    return shown + (f" and {len(loops) - most} more" if len(loops) > most else "")
