"""Issue 35 item 2: a position is evidence only after it has shown it is one: it moves with
OP's direction, in OP's scale, without a lag longer than a sample or two; otherwise the
verdict is OP and PV's, the reason says the position was not used and why, and
``Assessment.position_use`` is ``not_a_position``. Each broken position is built from the
product's own simulator (the ``vp`` of a simulation is the valve's true position)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

import stiction
from stiction import Verdict
from stiction.diagnosis.travel import MEASURED, NOT_USED
from stiction.scenarios import scenario, simulate
from stiction.scenarios.named import SimResult


def _late(vp: np.ndarray, k: int = 5) -> np.ndarray:
    return np.concatenate((np.full(k, vp[0]), vp[:-k]))


def _lagged(vp: np.ndarray, tau: float = 5.0) -> np.ndarray:
    out, a = vp.copy(), np.exp(-1.0 / tau)
    for i in range(1, vp.size):
        out[i] = a * out[i - 1] + (1.0 - a) * vp[i]
    return out


BROKEN: dict[str, Callable[[SimResult], np.ndarray]] = {
    "inverted": lambda s: 100.0 - s.vp,
    "PV wired in": lambda s: s.pv,
    "a 0-1 fraction": lambda s: s.vp / 100.0,
    "frozen": lambda s: np.full_like(s.vp, s.vp[0]),
    "lagged 5 s": lambda s: _lagged(s.vp),
}


def _not_used(sim: SimResult, pos: np.ndarray, why: str) -> stiction.Assessment:
    """The assessment with ``pos``: OP and PV's verdict, the position not used, ``why``."""
    plain = stiction.analyze(sim.op, sim.pv, ts=1.0)
    a = stiction.analyze(sim.op, sim.pv, ts=1.0, position=pos)
    assert a.verdict == plain.verdict, a.reason
    assert a.confidence == plain.confidence
    assert a.position_use == "not_a_position"
    assert MEASURED not in a.reason
    assert a.reason.startswith(plain.reason)
    said = a.reason.removeprefix(plain.reason)
    assert f"{NOT_USED}: " in said and why in said, said
    return a


def test_an_inverted_position_on_a_very_sticky_valve() -> None:
    """Was ``no_stiction`` 0.0 "band -54.3" on the paper's stickiest valve."""
    sim = simulate("table4-case2", duration=3600.0, noise=0.05, seed=1)
    a = _not_used(sim, 100.0 - sim.vp, "went against OP's travel")
    assert a.verdict == Verdict.STICTION


def test_pv_wired_in_as_the_position_on_a_good_valve() -> None:
    """Was ``stiction`` 1.0: a good valve under a sine load, PV in the position's place."""
    sim = simulate("disturbance", duration=7200.0, noise=0.02, seed=1)
    a = _not_used(sim, sim.pv, "went against OP's travel")
    assert a.verdict == Verdict.NO_STICTION


def test_a_fraction_is_not_in_op_units() -> None:
    """The sticky valve's position as a 0-1 fraction: its band read in OP units, its slip in
    the fraction's, gave fd, fs 100 times off."""
    sim = simulate("table4-case1", duration=3600.0, noise=0.05, seed=1)
    _not_used(sim, sim.vp / 100.0, "not in OP's units")


def test_a_frozen_position_while_pv_follows_op() -> None:
    """Was ``valve_not_responding``: the position held at its first value while the good
    valve moved and PV with it."""
    sim = simulate("disturbance", duration=3600.0, noise=0.05, seed=1)
    a = _not_used(sim, np.full_like(sim.vp, sim.vp[0]), "held while OP ran and PV moved")
    assert a.verdict == Verdict.NO_STICTION


@pytest.mark.parametrize(("seed", "duration"), [(3, 1800.0), (0, 7200.0)])
def test_a_late_position_on_an_aggressively_tuned_loop(seed: int, duration: float) -> None:
    """Read 5 samples late, the good valve of a loop ringing at its resonance showed a band
    of 5 samples' OP travel: ``stiction`` 0.56-0.70."""
    sim = simulate("aggressive-tuning", duration=duration, noise=0.02, seed=seed)
    a = _not_used(sim, _late(sim.vp), "lags OP by about 5 samples")
    assert a.verdict != Verdict.STICTION


def test_a_lagged_position_on_an_aggressively_tuned_loop() -> None:
    sim = simulate("aggressive-tuning", duration=1800.0, noise=0.02, seed=3)
    _not_used(sim, _lagged(sim.vp), "")


@pytest.mark.parametrize("name", ["table4-case2", "table9", "disturbance",
                                  "aggressive-tuning"])
def test_every_broken_position_leaves_op_and_pv_to_decide(name: str) -> None:
    """Sticky and good valves, each broken position; the true position is used."""
    sim = simulate(scenario(name), duration=3600.0, noise=0.05, seed=3)
    for kind, broken in BROKEN.items():
        a = stiction.analyze(sim.op, sim.pv, ts=1.0, position=broken(sim))
        assert a.position_use == "not_a_position", (kind, a.reason)
        assert MEASURED not in a.reason, kind
    a = stiction.analyze(sim.op, sim.pv, ts=1.0, position=sim.vp)
    assert a.position_use == "used" and MEASURED in a.reason, a.reason


def test_a_position_read_late_keeps_a_sticky_valves_verdict() -> None:
    """The limit of the lag test: a band that OP's travel over the lag does not explain is
    friction; the sticky valve's position read 5 samples late is used, its band within
    OP's travel over those samples of the true one."""
    sim = simulate("table4-case2", duration=3600.0, noise=0.05, seed=1)
    true = stiction.analyze(sim.op, sim.pv, ts=1.0, position=sim.vp)
    late = stiction.analyze(sim.op, sim.pv, ts=1.0, position=_late(sim.vp))
    assert late.verdict == true.verdict == Verdict.STICTION
    assert late.position_use == "used"
    assert true.band_op is not None and late.band_op is not None
    travel_5 = 5 * float(np.median(np.abs(np.diff(sim.op))))
    assert abs(late.band_op - true.band_op) <= travel_5 + 0.05 * true.band_op
