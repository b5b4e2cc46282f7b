"""check-config's count of the plant step's memory (issue 29) against what the step holds.

The estimate (:func:`gateway.config.checks.plant_bytes`) must not be lower than the peak of
the analysis in the worker (traced) plus the job's copies in the gateway, nor so high that
it refuses configs that would fit (at most twice the peak on a large job)."""

from __future__ import annotations

import pickle
import tracemalloc

import numpy as np

from gateway.config import LoopConfig, PointConfig
from gateway.config.checks import PLANT_BYTES_FIXED, PLANT_BYTES_PER_SAMPLE
from gateway.core.plant import PlantJob, analyze_plant_job
from stiction import Assessment, Verdict


def _job(loops: int, n: int) -> PlantJob:
    """``loops`` loops sharing one square cycle (every one called stiction: the worst case,
    each member fitted), in noise."""
    rng = np.random.default_rng(0)
    t = np.arange(n)
    wave = np.sign(np.sin(2 * np.pi * t / (n / 20)))
    op = (np.sin(2 * np.pi * t / (n / 20))[None, :] * rng.uniform(0.5, 2, (loops, 1))
          + rng.normal(0, 1, (loops, n))).astype(np.float32)
    pv = (wave[None, :] * rng.uniform(0.5, 2, (loops, 1))
          + rng.normal(0, 1, (loops, n))).astype(np.float32)
    names = tuple(f"L{i}" for i in range(loops))
    sus = Assessment(Verdict.STICTION, "suspected", oscillating=True, confidence=0.8)
    return PlantJob(tuple(range(loops)), names, op, pv, 1.0, dict.fromkeys(names, sus),
                    dict.fromkeys(names, "self-regulating"))


def test_the_estimate_covers_the_plant_steps_peak() -> None:
    loops, n = 60, 8192
    blob = pickle.dumps(_job(loops, n))
    analyze_plant_job(_job(2, 1024))  # the imports and caches a worker holds anyway
    tracemalloc.start()
    try:
        pa = analyze_plant_job(pickle.loads(blob))
        _now, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert pa.groups  # the worst case: a group, every member's evidence
    in_gateway = 16 * loops * n  # the job (float32 OP and PV) and its pickle
    estimate = PLANT_BYTES_FIXED + PLANT_BYTES_PER_SAMPLE * loops * n
    assert peak + in_gateway <= estimate
    assert estimate <= 2 * (peak + in_gateway), (estimate, peak + in_gateway)


def test_check_config_counts_every_time_base_averaged() -> None:
    from gateway.config.checks import plant_bytes  # noqa: PLC0415
    from gateway.config.model import Config, DeviceConfig, PlantSettings  # noqa: PLC0415

    devs = (DeviceConfig("a", "memory", 1.0, 1.0, None), DeviceConfig("b", "memory", 5.0, 1.0,
                                                                       None))
    loops = tuple(LoopConfig(f"A{i}", "a", PointConfig(None), PointConfig(None), 0,
                             window_s=65536.0) for i in range(100))
    loops += tuple(LoopConfig(f"B{i}", "b", PointConfig(None), PointConfig(None), 0,
                              window_s=5000.0) for i in range(3))
    loops += (LoopConfig("C", "b", PointConfig(None), PointConfig(None), 0, window_s=300.0),)
    cfg = Config("x", devs, loops, plant=PlantSettings(max_samples=1024))
    total, largest = plant_bytes(cfg)
    # 100 loops of 65,536 samples averaged by 64 to 1,024; 3 loops of 1,000 samples; C alone
    assert largest == (100, 1024)
    assert total == 2 * PLANT_BYTES_FIXED + PLANT_BYTES_PER_SAMPLE * (100 * 1024 + 3 * 1000)
    off = Config("x", devs, loops, plant=PlantSettings(enabled=False))
    assert plant_bytes(off) == (0, None)
