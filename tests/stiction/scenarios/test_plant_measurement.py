"""What a plant's signals go through before they are written (issue 37 item 2): a loop's PV
transmitter lag, an indicator of a loop's process value or valve, a historian's resolution."""

from __future__ import annotations

import numpy as np
import pytest

from stiction import ParameterError
from stiction.scenarios.plant import Indicator, PlantLoop, PlantScenario, simulate_plants

FIC = PlantLoop("FIC1", kp=1.0, tau=8.0, theta=2.0, kc=0.8, ti=150.0, fs=0.03, fd=0.015,
                k=1.99, sp_step=2.0, noise_sd=0.0)


def _lag_of(a: np.ndarray, b: np.ndarray) -> int:
    """Samples by which ``b`` follows ``a`` (the cross-correlation's peak)."""
    x, y = a - a.mean(), b - b.mean()
    c = np.correlate(y, x, mode="full")
    return int(np.argmax(c)) - (x.size - 1)


def test_a_slow_transmitter_lags_the_pv_and_a_second_meter_reads_the_process() -> None:
    slow = PlantLoop(**{**FIC.__dict__, "sensor_tau": 30.0})
    inds = (Indicator("FI_PROC", "FIC1", signal="process", tau=1e-6, noise_sd=0.0),
            Indicator("FI_VALVE", "FIC1", signal="valve", tau=1e-6, noise_sd=0.0),
            Indicator("FI_PV", "FIC1", tau=1e-6, noise_sd=0.0))
    (rec,) = simulate_plants([PlantScenario("m", (slow,), indicators=inds)], duration=3600.0,
                             seed=1)
    pv, proc = rec.pv["FIC1"], rec.indicators["FI_PROC"]
    assert 20 <= _lag_of(proc, pv) <= 40  # the PV follows the process by about its 30 s lag
    assert np.allclose(rec.indicators["FI_PV"], pv, atol=1e-6)
    assert np.allclose(rec.indicators["FI_VALVE"], rec.vp["FIC1"], atol=1e-6)


def test_a_historians_resolution_writes_steps() -> None:
    coarse = PlantLoop(**{**FIC.__dict__, "quantum": 0.5, "noise_sd": 0.05})
    inds = (Indicator("TI", "FIC1", quantum=0.25),)
    (rec,) = simulate_plants([PlantScenario("q", (coarse,), indicators=inds)], duration=600.0,
                             seed=1)
    for x, q in ((rec.op["FIC1"], 0.5), (rec.pv["FIC1"], 0.5), (rec.indicators["TI"], 0.25)):
        assert np.allclose(x / q, np.round(x / q)) and np.unique(x).size > 3


def test_an_indicator_of_an_unknown_signal_is_refused() -> None:
    sc = PlantScenario("bad", (FIC,), indicators=(Indicator("X", "FIC1", signal="flow"),))
    with pytest.raises(ParameterError, match="indicator X reads signal 'flow'"):
        simulate_plants([sc], duration=60.0)
