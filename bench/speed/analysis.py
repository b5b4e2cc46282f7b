"""Speed of ``stiction.analyze`` with every test, this tree beside the baseline (main when
issue 28 was filed, ``BENCH_BASELINE`` for another commit) in one run: median CPU time on a
3600-sample window at Ts 1 s as a ratio to one FFT of the same window timed in the same run
(``numpy.fft.rfft`` of 3600 float64 values, median of many calls; target (issue 28): analyze
at most 200 FFTs, about 5.8 ms where that FFT takes 29 us), its growth with the window
length (should be about linear), and where a sticky window's time goes, stage by stage.

The two versions are imported side by side (bench/_baseline.py) and timed interleaved, call
by call, so both see the same load; each window's results must be identical (printed).
Times are CPU time of this process (``time.process_time``), not wall time: on a shared
2-core box other processes stretch wall time by up to 2x, not the work done. The SI-only
detector (He et al. 2007: oscillation and stiction index, as the product had it before the
several tests) is timed beside them."""

from __future__ import annotations

import functools
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from bench._baseline import StageClock, analyze_of, baseline_stiction
from stiction import analyze
from stiction.detectors.stiction_index import stiction_index
from stiction.scenarios import simulate
from stiction.signal.oscillation import detect_oscillation

TARGET_FFTS = 200.0  # analyze's median at most this many FFTs of the same window (issue 28)
CASES: list[tuple[str, str, dict[str, Any]]] = [
    ("stiction, sized (table4-case2)", "table4-case2", {"kp": 1.0}),
    ("stiction, sized (table5-case2, integrating)", "table5-case2",
     {"kp": 0.2, "process": "integrating"}),
    ("no stiction (disturbance)", "disturbance", {"kp": 1.0}),
    ("not oscillating (healthy)", "healthy", {"kp": 1.0}),
]
LENGTHS = (1800, 3600, 7200, 14400)


def _cpu(call: Callable[[], Any]) -> float:
    t0 = time.process_time()
    call()
    return time.process_time() - t0


def _median_ms(calls: dict[str, Callable[[], Any]], repeat: int) -> dict[str, float]:
    """Median CPU ms of each call, the calls interleaved (their order turning each round)."""
    for call in calls.values():
        call()  # warm-up
    names = list(calls)
    times: dict[str, list[float]] = {n: [] for n in names}
    for r in range(repeat):
        for n in names[r % len(names):] + names[: r % len(names)]:
            times[n].append(_cpu(calls[n]))
    return {n: 1e3 * statistics.median(t) for n, t in times.items()}


def _fft_ms(x: np.ndarray, repeat: int = 2001) -> float:
    """Median CPU time of one ``numpy.fft.rfft`` of ``x`` (float64), ms, over ``repeat``
    calls back to back (the window in cache: the steadiest and the fastest figure; the
    first call after an ``analyze`` takes two to three times as long)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    rfft = np.fft.rfft
    rfft(x)  # warm-up
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        rfft(x)
        times.append(time.process_time() - t0)
    return 1e3 * statistics.median(times)


def _si_only(op: np.ndarray, pv: np.ndarray, integrating: bool) -> None:
    x = pv if integrating else op
    osc = detect_oscillation(x)
    if osc.oscillating and osc.period is not None and osc.period >= 8:
        stiction_index(x, osc.period)


def _case(label: str, name: str, kw: dict[str, Any], versions: dict[str, Callable[..., Any]]
          ) -> None:
    res = simulate(name, duration=14400.0, noise=0.05, seed=1)
    op, pv = res.op, res.pv
    results = {v: fn(op[:3600], pv[:3600], ts=1.0, **kw) for v, fn in versions.items()}
    same = results["before"].to_dict() == results["after"].to_dict()
    fft = _fft_ms(op[:3600])
    ms = {n: _median_ms({v: functools.partial(fn, op[:n], pv[:n], ts=1.0, **kw)
                         for v, fn in versions.items()}, 21 if n <= 3600 else 7)
          for n in LENGTHS}
    fft = statistics.median([fft, _fft_ms(op[:3600])])
    integ = kw.get("process") == "integrating"
    base = _median_ms({"si": functools.partial(_si_only, op[:3600], pv[:3600], integ)},
                      21)["si"]
    before, after = ms[3600]["before"], ms[3600]["after"]
    flag = "ok" if after / fft <= TARGET_FFTS else "over target"
    print(f"{label:<46} verdict {results['after'].verdict!s:<15} "
          f"{'same result' if same else 'RESULTS DIFFER'} (one rfft {1e3 * fft:.1f} us)")
    print(f"{'':<4}3600 samples: before {before:6.2f} ms = {before / fft:4.0f} FFTs, after "
          f"{after:6.2f} ms = {after / fft:4.0f} FFTs ({flag}, target {TARGET_FFTS:g}); "
          f"x{before / after:.2f}; SI only {base:.2f} ms = {base / fft:.0f} FFTs")
    for v in versions:
        growth = "  ".join(f"{n}: {ms[n][v]:.2f} ms" for n in LENGTHS)
        print(f"{'':<4}growth {v:<6} {growth}  (x{ms[14400][v] / ms[1800][v]:.1f} for x8 "
              "samples)")


def _stages(name: str, kw: dict[str, Any], packages: dict[str, Any], repeat: int = 21
            ) -> None:
    """Where the time of one window goes, stage by stage, both versions."""
    res = simulate(name, duration=14400.0, noise=0.05, seed=1)
    op, pv = res.op[:3600], res.pv[:3600]
    fft = _fft_ms(op)
    clocks = {v: StageClock(p) for v, p in packages.items()}
    rows: dict[str, dict[str, float]] = {}
    for v, clock in clocks.items():
        per_run = []
        with clock:
            clock.run(op, pv, ts=1.0, **kw)  # warm-up
            for _ in range(repeat):
                clock.reset()
                clock.run(op, pv, ts=1.0, **kw)
                per_run.append(clock.rows())
        rows[v] = {k: statistics.median(r[k] for r in per_run) for k in per_run[0]}
    print(f"where the time of one {name} window (3600 samples) goes, CPU ms and FFTs "
          f"(medians of {repeat}; one rfft {1e3 * fft:.1f} us):")
    print(f"{'stage':<16} {'before ms':>9} {'FFTs':>5} {'after ms':>9} {'FFTs':>5}")
    for stage in rows["after"]:
        b, a = 1e3 * rows["before"].get(stage, 0.0), 1e3 * rows["after"][stage]
        print(f"{stage:<16} {b:>9.2f} {b / fft:>5.0f} {a:>9.2f} {a / fft:>5.0f}")


def main() -> None:
    with baseline_stiction() as (commit, package):
        print(f"== analyze() speed: before = main at {commit}, after = this tree ==")
        versions = {"before": analyze_of(package), "after": analyze}
        for label, name, kw in CASES:
            _case(label, name, kw, versions)
        import stiction  # noqa: PLC0415 - this tree's package, beside the baseline's

        _stages("table4-case2", CASES[0][2], {"before": package, "after": stiction})


if __name__ == "__main__":
    main()
