"""Speed of ``stiction.analyze`` with every test: median time on a 3600-sample window at Ts
1 s, as a ratio to one FFT of the same window timed in the same run (``numpy.fft.rfft`` of
3600 float64 values, median of many calls; target: analyze at most 120 FFTs, about 5 ms
where that FFT takes 42 us), and its growth with the window length (should be about
linear).

Times are CPU time of this process (``time.process_time``), not wall time: on a shared
2-core box other processes stretch wall time by up to 2x, not the work done. The
SI-only detector (He et al. 2007: oscillation and stiction index, as the product had it
before the several tests) is timed beside it in the same run."""

from __future__ import annotations

import functools
import statistics
import time
from typing import Any

import numpy as np

from stiction import analyze
from stiction.detectors.stiction_index import stiction_index
from stiction.scenarios import simulate
from stiction.signal.oscillation import detect_oscillation

TARGET_MS = 5.0
TARGET_FFTS = 120.0  # analyze's median at most this many FFTs of the same window (issue 24)


def _median_ms(op: np.ndarray, pv: np.ndarray, repeat: int, fn: Any = None, **kw: Any
               ) -> float:
    call = fn or (lambda: analyze(op, pv, ts=1.0, **kw))
    call()  # warm-up
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        call()
        times.append(time.process_time() - t0)
    return 1e3 * statistics.median(times)


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


def main() -> None:
    print("== analyze() speed ==")
    cases = [
        ("stiction, sized (table4-case2)", "table4-case2", {"kp": 1.0}),
        ("stiction, sized (table5-case2, integrating)", "table5-case2", {"kp": 0.2}),
        ("no stiction (disturbance)", "disturbance", {"kp": 1.0}),
        ("not oscillating (healthy)", "healthy", {"kp": 1.0}),
    ]
    for label, name, kw in cases:
        res = simulate(name, duration=14400.0, noise=0.05, seed=1)
        proc = {"process": "integrating"} if name.startswith("table5") else {}
        a = analyze(res.op[:3600], res.pv[:3600], ts=1.0, **kw, **proc)  # type: ignore[arg-type]
        fft = _fft_ms(res.op[:3600])
        ms = {n: _median_ms(res.op[:n], res.pv[:n], 21 if n <= 3600 else 7, **kw, **proc)
              for n in (1800, 3600, 7200, 14400)}
        fft_after = _fft_ms(res.op[:3600])
        fft = statistics.median([fft, fft_after])
        ratio = ms[3600] / fft
        flag = "ok" if ratio <= TARGET_FFTS else "over target"
        integ = name.startswith("table5")
        base = _median_ms(res.op[:3600], res.pv[:3600], 21,
                          fn=functools.partial(_si_only, res.op[:3600], res.pv[:3600], integ))
        print(f"{label:<46} verdict {a.verdict!s:<15} 3600 samples: {ms[3600]:6.2f} ms "
              f"= {ratio:5.0f} FFTs ({flag}, target {TARGET_FFTS:g}; one rfft "
              f"{1e3 * fft:.1f} us; SI only {base:.2f} ms = {base / fft:.0f} FFTs)")
        growth = "  ".join(f"{n}: {v:.2f} ms" for n, v in ms.items())
        print(f"{'':<46} growth  {growth}  (x{ms[14400] / ms[1800]:.1f} for x8 samples)")


if __name__ == "__main__":
    main()
