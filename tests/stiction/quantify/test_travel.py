"""Stiction measured from the valve's travel (``stiction.quantify.travel``) on simulated
loops whose valve is known: He's (K 1 and 1.99), Choudhury's and Kano's models, their
position read with a positioner's noise; a good valve; a valve that does not follow."""

from __future__ import annotations

import numpy as np
import pytest
from valve_loops import run_loops

from stiction import ParameterError
from stiction.models.valves import ChoudhuryValve, HeValve, KanoValve
from stiction.quantify.travel import (
    FOLLOWS,
    NOT_RESPONDING,
    STICKS,
    UNUSABLE,
    measure_travel,
)

FS = np.array([0.02, 0.05, 0.20])
FD = np.array([0.01, 0.04, 0.18])
S = np.array([0.02, 0.05, 0.03])
J = np.array([0.005, 0.01, 0.015])


def _close(measured: float | None, true: float) -> None:
    assert measured is not None
    assert measured == pytest.approx(true, rel=0.10)


@pytest.mark.parametrize("k", [1.0, 1.99])
@pytest.mark.parametrize("integrating", [False, True])
def test_he_valve_band_slip_fd_fs_within_10_percent(k: float, integrating: bool) -> None:
    """He's model: the band is 2 fs - J (fs + fd at K = 1), the slip J = K (fs - fd)."""
    extra = {"integrating": True, "kp": 0.05, "ti": 200.0} if integrating else {}
    runs = run_loops(HeValve(FS, FD, k), 3, pv_noise=0.05, position_noise=0.05, **extra)
    for r, fs, fd in zip(runs, FS * 100, FD * 100, strict=True):
        t = measure_travel(r.op, r.position, k=k, span=100.0)
        assert t.status == STICKS, t.note
        slip = k * (fs - fd)
        _close(t.band, 2 * fs - slip)
        _close(t.slip, slip)
        _close(t.fs, fs)
        _close(t.fd, fd)


def test_kano_valve_band_and_slip_within_10_percent() -> None:
    runs = run_loops(KanoValve(S, J), 3, pv_noise=0.05, position_noise=0.05)
    runs += run_loops(KanoValve(S, J), 3, pv_noise=0.05, position_noise=0.05,
                      integrating=True, kp=0.05, ti=200.0)
    for r, s, j in zip(runs, np.tile(S * 100, 2), np.tile(J * 100, 2), strict=True):
        t = measure_travel(r.op, r.position, span=100.0)
        assert t.status == STICKS, t.note
        _close(t.band, s)
        _close(t.slip, j)
        _close(t.fs, (s + j) / 2)  # He's terms, K = 1
        _close(t.fd, (s - j) / 2)


def test_choudhury_valve_band_and_slip_within_10_percent() -> None:
    """Choudhury's flowchart sticks at every reversal of its input, so OP's noise makes the
    simulated valve jump back and forth by J (the reason Kano et al. revised it): its loops
    run without PV noise; the position carries the positioner's."""
    runs = run_loops(ChoudhuryValve(S, J), 3, position_noise=0.05, integrating=True,
                     kp=0.05, ti=200.0)
    runs += run_loops(ChoudhuryValve(S, J), 3, position_noise=0.05, dist_amp=0.01,
                      dist_period=900.0)
    for r, s, j in zip(runs, np.tile(S * 100, 2), np.tile(J * 100, 2), strict=True):
        t = measure_travel(r.op, r.position, span=100.0)
        assert t.status == STICKS, t.note
        _close(t.band, s)
        _close(t.slip, j)


def test_good_valve_in_a_disturbed_loop_follows() -> None:
    """A perfect valve under a sinusoidal load: OP and the valve cycle together."""
    (r,) = run_loops(HeValve(0.0, 0.0, 1.0), 1, pv_noise=0.05, position_noise=0.05,
                     dist_amp=0.05, dist_period=300.0)
    t = measure_travel(r.op, r.position, span=100.0)
    assert t.status == FOLLOWS, t.note
    assert t.reversals >= 10
    assert t.sticking == 0


def test_a_valve_that_does_not_follow_op() -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, pv_noise=0.05)
    held = np.full_like(r.op, 37.0) + np.random.default_rng(3).normal(0, 0.05, r.op.size)
    t = measure_travel(r.op, held, span=100.0)
    assert t.status == NOT_RESPONDING, t.note
    assert "held" in t.note


def test_a_calm_loop_cannot_tell() -> None:
    """OP and the valve at rest: nothing to measure (the caller keeps OP/PV's verdict)."""
    rng = np.random.default_rng(5)
    op = 50 + rng.normal(0, 0.05, 3000)
    t = measure_travel(op, np.full(3000, 50.0), span=100.0)
    assert t.status == UNUSABLE


@pytest.mark.parametrize("missing", [1.0, 0.5])
def test_a_position_without_samples_is_unusable(missing: float) -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1)
    pos = r.position.copy()
    pos[: int(missing * pos.size)] = np.nan
    t = measure_travel(r.op, pos)
    assert t.status == UNUSABLE
    assert "samples with both OP and the position" in t.note


def test_short_gaps_in_the_position_are_filled() -> None:
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, position_noise=0.05)
    pos = r.position.copy()
    pos[::50] = np.nan  # 2 % missing
    t = measure_travel(r.op, pos)
    assert t.status == STICKS
    _close(t.band, 5.0)


def test_bad_arguments_are_named() -> None:
    with pytest.raises(ParameterError, match="position"):
        measure_travel(np.zeros(100), np.zeros(99))
    with pytest.raises(ParameterError, match="k"):
        measure_travel(np.zeros(100), np.zeros(100), k=3.0)
