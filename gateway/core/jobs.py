"""What an analysis worker runs: window copies in, assessments out (no IO, picklable).

:func:`batches` copies windows out of the ring buffers, ``batch_size`` loops at a time (one
pickle per batch, not per loop); :func:`analyze_batch` is the worker's entry point: per job
the window fill, the trailing usable segment (short gaps interpolated), a ``bad_data``
verdict when the device delivered implausible values, else ``stiction.analyze`` (or the
function named by ``path``, for tests); its ``not_oscillating`` on a segment shorter than
the window is ``warming_up`` (:func:`warming_up`).
"""

from __future__ import annotations

import dataclasses
import importlib
import time
from collections.abc import Callable, Iterator, Sequence

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment, Verdict
from stiction.diagnosis.enough import (
    JUDGE_SAMPLES,
    SEE_CYCLES,
    TOO_SHORT,
    TooShort,
    duration,
    movement_scales,
    too_short,
)
from stiction.ranking import swing

from .points import Quality
from .windows import LoopGroup, position_segment, segment_of

__all__ = ["BAD_TAIL", "DEFAULT_ANALYZE", "FULL_WINDOW", "MIN_SEGMENT", "LoopJob",
           "analyze_batch", "bad_values_reason", "batches", "warming_up"]

DEFAULT_ANALYZE = "stiction:analyze"
BAD_TAIL = 3  # trailing BAD samples beyond which the current data is called unusable
MIN_SEGMENT = 32  # stiction.analyze's minimum window
FULL_WINDOW = 0.95
"""Share of the window the analysed segment must span before it counts as full, and
``not_oscillating`` as final (a few samples short of the whole: the latest poll may have
failed)."""


@dataclasses.dataclass(frozen=True)
class LoopJob:
    """What a worker needs to analyse one loop (picklable)."""

    index: int  # loop index in the store
    op: NDArray[np.float32]
    pv: NDArray[np.float32]
    quality: NDArray[np.uint8]
    size: int  # window length in samples (for the fill ratio)
    ts: float
    kp: float | None
    delay: float
    process: str
    op_range: tuple[float, float]
    position: NDArray[np.float32] | None = None  # the valve's position (NaN: not GOOD)


def batches(groups: Sequence[LoopGroup], batch_size: int) -> Iterator[list[LoopJob]]:
    """The jobs of every loop with samples, ``batch_size`` at most per list; each batch's
    windows are copied only when the iterator reaches it."""
    for g in groups:
        if g.bank.count == 0:
            continue
        for lo in range(0, len(g.configs), batch_size):
            cols = np.arange(lo, min(lo + batch_size, len(g.configs)))
            _t, op, pv, q = g.bank.series(cols)
            pos = g.bank.positions(cols)
            batch = []
            for k, c in enumerate(cols.tolist()):
                cfg = g.configs[c]
                batch.append(LoopJob(int(g.rows[c]), op[k], pv[k], q[k], g.bank.size, g.ts,
                                     cfg.kp, cfg.delay_s, cfg.process, cfg.op_range,
                                     pos[k] if pos is not None and cfg.position is not None
                                     else None))
            yield batch


_FUNCS: dict[str, Callable[..., Assessment]] = {}


def resolve(path: str) -> Callable[..., Assessment]:
    """The analysis function ``module:name`` (imported once per process)."""
    fn = _FUNCS.get(path)
    if fn is None:
        module, _, name = path.partition(":")
        fn = getattr(importlib.import_module(module), name)
        _FUNCS[path] = fn
    return fn


def analyze_batch(path: str, jobs: Sequence[LoopJob]
                  ) -> list[tuple[int, Assessment, float, int, float, float | None]]:
    """Worker entry: (index, assessment, window fill, samples used, seconds, the PV's swing
    over the samples used: :func:`stiction.ranking.swing`) per job."""
    analyze = resolve(path)
    out = []
    for job in jobs:
        t0 = time.perf_counter()
        fill = float(np.count_nonzero(job.quality == Quality.GOOD)) / job.size
        op, pv, start = segment_of(job.op, job.pv, job.quality)
        position = (None if job.position is None
                    else position_segment(job.position, start, len(op)))
        reason = bad_values_reason(job.quality, len(op))
        if reason is not None:
            a = Assessment(Verdict.BAD_DATA, reason)
        elif len(op) < 2:
            a = Assessment(Verdict.BAD_DATA, "no usable samples in the window yet")
        elif len(op) >= FULL_WINDOW * job.size:
            a = _analyze(analyze, job, op, pv, position)
        elif len(op) < JUDGE_SAMPLES:  # too short for any verdict: not even analysed
            a = warming_up(Assessment(Verdict.WARMING_UP, ""), len(op), job.size, job.ts,
                           fill, short=too_short(len(op), waiting=True))
        else:
            a = _while_filling(_analyze(analyze, job, op, pv, position), op, pv, job, fill)
        out.append((job.index, a, fill, len(op), time.perf_counter() - t0, swing(pv)))
    return out


def _analyze(analyze: Callable[..., Assessment], job: LoopJob, op: NDArray[np.float64],
             pv: NDArray[np.float64], position: NDArray[np.float64] | None) -> Assessment:
    """``analyze`` on the segment; ``position`` passed only where the loop reads one (an
    analysis function of a test need not know the keyword)."""
    extra = {} if position is None else {"position": position}
    try:
        return analyze(op, pv, ts=job.ts, kp=job.kp, delay=job.delay, process=job.process,
                       op_range=job.op_range, **extra)
    except Exception as exc:  # a bug in one window must not stop the round
        return Assessment(Verdict.BAD_DATA, f"analysis failed: {type(exc).__name__}: {exc}")


def _while_filling(a: Assessment, op: NDArray[np.float64], pv: NDArray[np.float64],
                   job: LoopJob, fill: float) -> Assessment:
    """``a``, or ``warming_up`` while the filling segment is too short to judge (module doc)."""
    period = None if a.period_s is None else a.period_s / job.ts
    short = too_short(len(op), period=period, scales=movement_scales(op, pv), waiting=True)
    withdrawn = short is not None and (short.withdraws(a.verdict) or (
        a.verdict == Verdict.BAD_DATA and a.reason.startswith(TOO_SHORT)))
    if withdrawn or a.verdict == Verdict.NOT_OSCILLATING:
        return warming_up(a, len(op), job.size, job.ts, fill, short=short)
    return a


def bad_values_reason(quality: NDArray[np.uint8], usable: int) -> str | None:
    """Why a window is bad_data because the device delivered implausible values (quality
    BAD: NaN, inf, subnormal, outside the configured range), or None. Communication gaps
    are not reported here: they make the loop stale."""
    bad = quality == Quality.BAD
    n_bad = int(np.count_nonzero(bad))
    if n_bad == 0:
        return None
    what = "NaN, inf, subnormal (word-swapped?) or outside the configured range"
    tail = len(quality) - int(np.flatnonzero(~bad)[-1]) - 1 if not bad.all() else len(quality)
    if tail > BAD_TAIL:
        return f"the latest {tail} samples are bad values ({what})"
    if usable < MIN_SEGMENT:
        return (f"only {usable} usable samples since the last run of bad values "
                f"({n_bad} bad samples in the window: {what})")
    return None


def warming_up(a: Assessment, samples: int, size: int, ts: float, fill: float, *,
               short: TooShort | None = None) -> Assessment:
    """``a`` as ``warming_up``: the window's ``samples`` (of ``size``) are too short to judge
    (``short``: why, by :func:`stiction.diagnosis.enough.too_short`), or hold no oscillation
    yet while a slower one may need more. The reason says how full the window is and what it
    waits for (under the journal's 200 characters); the analysis's own reason stays in the
    evidence's notes."""
    head = (f"warming up: window fill {fill:.0%}, {duration(samples * ts)} of "
            f"{duration(size * ts)} analysed; ")
    if short is None:
        reason = (f"{head}no oscillation faster than {duration(samples * ts / SEE_CYCLES)} so "
                  f"far; slower ones need 3 cycles: waiting up to "
                  f"{duration((size - samples) * ts)} for the full window, which sees "
                  f"periods up to {duration(size * ts / SEE_CYCLES)}")
    else:
        scale = duration((short.scale or 0.0) * ts)
        why = {"samples": f"a verdict needs {JUDGE_SAMPLES} samples",
               "cycles": f"its cycle of {scale} shows in {SEE_CYCLES:g} cycles",
               "movement": f"OP and PV move on a {scale} time scale (a cycle that slow "
                           f"shows in {SEE_CYCLES:g} of it)"}[short.basis]
        reason = (f"{head}{why}: judged in {duration((min(short.need, size) - samples) * ts)} "
                  f"at the earliest, calm only when full in {duration((size - samples) * ts)}")
    return dataclasses.replace(a, verdict=Verdict.WARMING_UP, reason=reason)
