"""He & Wang (2014) quantification on analytic valve moves: multi-jump and its limits."""

from __future__ import annotations

import numpy as np
import pytest
from analytic_signals import first_order, square_vp
from scipy import signal

from stiction.quantify.hewang import quantify

RNG = np.random.default_rng(42)


@pytest.mark.parametrize(("double", "expected"), [(False, False), (True, True)])
def test_multi_jump_check(double: bool, expected: bool) -> None:
    vp, _ = square_vp(6000, 500, double=double)
    pv = 50 + first_order(vp - 50, 100.0) + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 100) / 1000.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.reason is None
    assert q.multi_jump is expected


def test_pv_creeping_between_single_jumps_is_not_multi_jump() -> None:
    """Plant PV rarely relaxes as one clean exponential: here it creeps back by a third of
    the swing between jumps (a slow load, a valve that creeps). That spoils the fit
    (``poor_fit``) but is no second jump, so ``multi_jump`` stays False."""
    vp, _ = square_vp(6000, 500, double=False)
    phase = (np.arange(vp.size) - 100) % 500 / 500.0
    creep = -1.3 * np.sign(vp - 50) * phase  # drifts back towards the middle
    pv = 50 + first_order(vp - 50, 100.0) + creep + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 100) / 1000.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.reason is None
    assert q.poor_fit >= 8  # of 10 half cycles
    assert q.multi_jump is False
    # OP swing 20 between the jumps, J = 4: fs = 12, fd = 12 - 4 / 1.99; fd reads OP only
    assert q.fd_op == pytest.approx(12 - 4 / 1.99, rel=0.01)
    assert q.fs_op == pytest.approx(12, rel=0.1)


def test_inconsistent_sizes_are_refused_not_reported() -> None:
    """When the PV switching points are not where OP turned (here OP is a sawtooth whose
    swing between the switches is ~0 while PV steps by 4), fd would come out <= 0: the
    quantification says so instead of reporting it."""
    vp, _ = square_vp(6000, 500, double=False)
    pv = 50 + first_order(vp - 50, 30.0) + RNG.normal(0, 0.02, vp.size)
    op = 50 + 10 * signal.sawtooth(2 * np.pi * (np.arange(vp.size) - 350) / 500.0, 0.5)
    q = quantify(op, pv, period=1000.0, ts=1.0, kp=1.0, delay=0.0, integrating=False, k=1.99)
    assert q.fd_op is None
    assert q.reason is not None and "inconsistent sizes" in q.reason
