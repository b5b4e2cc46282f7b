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

from .points import Quality
from .windows import LoopGroup, analysis_segment

__all__ = ["BAD_TAIL", "DEFAULT_ANALYZE", "FULL_WINDOW", "MIN_SEGMENT", "LoopJob",
           "analyze_batch", "bad_values_reason", "batches", "warming_up"]

DEFAULT_ANALYZE = "stiction:analyze"
BAD_TAIL = 3  # trailing BAD samples beyond which the current data is called unusable
MIN_SEGMENT = 32  # stiction.analyze's minimum window
FULL_WINDOW = 0.95
"""Share of the window the analysed segment must span before ``not_oscillating`` is final
(a few samples short of the whole: the latest poll may have failed)."""
CYCLES_TO_SEE = 2.6
"""Cycles of an oscillation a window must hold before the analysis can see it: its ACF test
needs four zero crossings within 2/3 of the window (7/4 periods <= 2/3 of it)."""


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


def batches(groups: Sequence[LoopGroup], batch_size: int) -> Iterator[list[LoopJob]]:
    """The jobs of every loop with samples, ``batch_size`` at most per list; each batch's
    windows are copied only when the iterator reaches it."""
    for g in groups:
        if g.bank.count == 0:
            continue
        for lo in range(0, len(g.configs), batch_size):
            cols = np.arange(lo, min(lo + batch_size, len(g.configs)))
            _t, op, pv, q = g.bank.series(cols)
            batch = []
            for k, c in enumerate(cols.tolist()):
                cfg = g.configs[c]
                batch.append(LoopJob(int(g.rows[c]), op[k], pv[k], q[k], g.bank.size, g.ts,
                                     cfg.kp, cfg.delay_s, cfg.process, cfg.op_range))
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
                  ) -> list[tuple[int, Assessment, float, int, float]]:
    """Worker entry: (index, assessment, window fill, samples used, seconds) per job."""
    analyze = resolve(path)
    out = []
    for job in jobs:
        t0 = time.perf_counter()
        fill = float(np.count_nonzero(job.quality == Quality.GOOD)) / job.size
        op, pv = analysis_segment(job.op, job.pv, job.quality)
        reason = bad_values_reason(job.quality, len(op))
        if reason is not None:
            a = Assessment(Verdict.BAD_DATA, reason)
        elif len(op) < 2:
            a = Assessment(Verdict.BAD_DATA, "no usable samples in the window yet")
        else:
            try:
                a = analyze(op, pv, ts=job.ts, kp=job.kp, delay=job.delay,
                            process=job.process, op_range=job.op_range)
            except Exception as exc:  # a bug in one window must not stop the round
                a = Assessment(Verdict.BAD_DATA, f"analysis failed: {type(exc).__name__}: {exc}")
            if a.verdict == Verdict.NOT_OSCILLATING and len(op) < FULL_WINDOW * job.size:
                a = warming_up(a, len(op), job.size, job.ts, fill)
        out.append((job.index, a, fill, len(op), time.perf_counter() - t0))
    return out


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


def warming_up(a: Assessment, samples: int, size: int, ts: float, fill: float) -> Assessment:
    """``a`` (``not_oscillating`` on ``samples`` of a window of ``size``) as ``warming_up``:
    the segment is too short to hold enough cycles of a slow oscillation, so the verdict is
    not final. The reason says how full the window is and what it waits for (under the
    journal's 200 characters); the analysis's own reason stays in the evidence's notes."""
    reason = (f"warming up: window fill {fill:.0%}, {_duration(samples * ts)} of "
              f"{_duration(size * ts)} analysed; no oscillation faster than "
              f"{_duration(samples * ts / CYCLES_TO_SEE)} so far; slower ones need 3 cycles: "
              f"waiting up to {_duration((size - samples) * ts)} for the full "
              f"window, which sees periods up to {_duration(size * ts / CYCLES_TO_SEE)}")
    return dataclasses.replace(a, verdict=Verdict.WARMING_UP, reason=reason)


def _duration(seconds: float) -> str:
    """``0.4 s``, ``45 s``, ``4 min``, ``1 h 50 min``, ``2 h``."""
    if seconds < 10:
        return f"{seconds:.2g} s"
    s = round(seconds)
    if s < 120:
        return f"{s} s"
    minutes = round(s / 60)
    hours, rest = divmod(minutes, 60)
    if hours == 0:
        return f"{minutes} min"
    return f"{hours} h" + (f" {rest} min" if rest else "")
