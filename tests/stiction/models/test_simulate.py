"""Closed-loop simulator and paper scenarios."""

from __future__ import annotations

import numpy as np
import pytest

from stiction import HeValve, ParameterError
from stiction.models.simulate import LoopBank, LoopParams
from stiction.scenarios import SCENARIOS, scenario, simulate


def jumps_and_forces(op: np.ndarray, vp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """VP jumps (% span) and the net force |OP - VP_before| (% span) at each jump."""
    d = np.diff(vp)
    idx = np.flatnonzero(np.abs(d) > 1e-9) + 1
    return np.abs(vp[idx] - vp[idx - 1]), np.abs(op[idx] - vp[idx - 1])


@pytest.mark.parametrize(("name", "overrides"), [("table4-case2", {}), ("table6", {"tau": 120.0})])
def test_stiction_limit_cycle_op_swing_is_2fd_and_vp_jumps_k_fs_minus_fd(
    name: str, overrides: dict[str, float]
) -> None:
    res = simulate(scenario(name, **overrides))
    sc = res.scenario
    settled = slice(len(res.t) // 3, None)
    op, vp = res.op[settled], res.vp[settled]
    jumps, forces = jumps_and_forces(op, vp)
    assert len(jumps) >= 4, "the loop must keep cycling"
    # OP swing per half cycle is 2 fd (eq 8): within 2 % of span
    assert np.ptp(op) == pytest.approx(200 * sc.fd, abs=2.0)
    # every jump is K (e - fd) with e the net force at the switch (eq 6) ...
    np.testing.assert_allclose(jumps, sc.k * (forces - 100 * sc.fd), rtol=1e-9)
    # ... and the valve breaks away on the first sample past fs, so e - fs is at most one
    # OP move: J = K (fs - fd) up to the sampling overshoot K * max|dOP|
    max_dop = np.abs(np.diff(op)).max()
    j_nominal = sc.k * (sc.fs - sc.fd) * 100
    assert (jumps > j_nominal - 1e-9).all()
    assert (jumps <= j_nominal + sc.k * max_dop + 1e-9).all()
    # and the jumps alternate in sign: one jump per half cycle
    signs = np.sign(np.diff(vp)[np.abs(np.diff(vp)) > 1e-9])
    assert (signs[1:] != signs[:-1]).all()


def test_table6_nominal_jump_within_one_percent_of_k_fs_minus_fd() -> None:
    res = simulate(scenario("table6", tau=120.0))
    jumps, _ = jumps_and_forces(res.op, res.vp)
    assert np.median(jumps) == pytest.approx(1.99 * 2.0, rel=0.01)


def test_bank_of_loops_equals_loops_run_one_by_one() -> None:
    taus = np.array([60.0, 150.0, 300.0])
    thetas = np.array([0.0, 2.5, 6.0])
    valve = HeValve(np.array([0.0, 0.05, 0.2]), np.array([0.0, 0.04, 0.18]), 1.99)
    bank = LoopBank(3, LoopParams(kc=2, ti=120, tau=taus, theta=thetas, noise_sd=0.0), valve)
    singles = [
        LoopBank(1, LoopParams(kc=2, ti=120, tau=taus[i], theta=thetas[i]),
                 HeValve(float(valve.fs[i]), float(valve.fd[i]), 1.99))  # type: ignore[index]
        for i in range(3)
    ]
    for k in range(600):
        sp = 52.0 if k > 10 else 50.0
        many = bank.step(sp)
        for i, one in enumerate(singles):
            o = one.step(sp)
            assert many.op[i] == pytest.approx(o.op[0], abs=1e-12)
            assert many.pv[i] == pytest.approx(o.pv[0], abs=1e-12)


def test_foptd_step_response_is_exact_with_fractional_dead_time() -> None:
    """Open loop (Kc = 0 keeps OP at x0): a load step at the process input gives
    Kp (1 - exp(-(t - theta)/tau)) at the sample times, fractional theta included."""
    kp, tau, theta = 1.5, 20.0, 3.4
    bank = LoopBank(1, LoopParams(kc=0.0, kp=kp, tau=tau, theta=theta), HeValve(0, 0, 1))
    # hold the valve at x0 + 0.1 = 0.6: a clamp range of one value pins OP there
    bank.valve_state = bank.valve.initial_state(np.array([0.6]))
    bank.op_lo[:] = 0.6 - 1e-12
    bank.op_hi[:] = 0.6
    pv = np.array([bank.step().pv[0] for _ in range(120)])
    t = np.arange(120.0)
    # the valve position of sample k acts from t = k + theta on (ZOH)
    t_eff = np.clip(t - theta, 0.0, None)
    expected = 50.0 + 100 * 0.1 * kp * (1 - np.exp(-t_eff / tau))
    np.testing.assert_allclose(pv, expected, atol=1e-9)


def test_integrating_process_ramps_with_slope_kp() -> None:
    bank = LoopBank(1, LoopParams(kc=0.0, kp=0.2, integrating=True, theta=1.0),
                    HeValve(0, 0, 1))
    bank.valve_state = bank.valve.initial_state(np.array([0.55]))
    bank.op_lo[:] = 0.55 - 1e-12
    bank.op_hi[:] = 0.55
    pv = np.array([bank.step().pv[0] for _ in range(50)])
    slopes = np.diff(pv[5:])
    np.testing.assert_allclose(slopes, 100 * 0.05 * 0.2, rtol=1e-9)


def test_controller_output_clamped_to_span_without_windup() -> None:
    bank = LoopBank(1, LoopParams(kc=5.0, ti=10.0, tau=30.0), HeValve(0, 0, 1))
    out = [bank.step(sp=200.0) for _ in range(100)]  # unreachable setpoint
    assert max(o.op[0] for o in out) == pytest.approx(100.0)
    # anti-windup: coming back, OP leaves the limit as soon as the error changes sign
    back = [bank.step(sp=0.0) for _ in range(5)]
    assert back[0].op[0] < 100.0


def test_seeded_noise_is_deterministic() -> None:
    a = simulate("healthy", duration=300, noise=0.5, seed=7)
    b = simulate("healthy", duration=300, noise=0.5, seed=7)
    c = simulate("healthy", duration=300, noise=0.5, seed=8)
    np.testing.assert_array_equal(a.pv, b.pv)
    assert not np.array_equal(a.pv, c.pv)
    assert np.std(np.diff(a.pv[100:])) == pytest.approx(0.5 * np.sqrt(2), rel=0.25)


def test_disturbance_scenario_oscillates_at_the_disturbance_period() -> None:
    res = simulate("disturbance")
    op = res.op[3000:] - res.op[3000:].mean()
    spectrum = np.abs(np.fft.rfft(op))
    freqs = np.fft.rfftfreq(len(op), d=1.0)
    assert 1 / freqs[np.argmax(spectrum[1:]) + 1] == pytest.approx(600.0, rel=0.05)


def test_healthy_settles_and_aggressive_tuning_keeps_ringing() -> None:
    healthy = simulate("healthy")
    assert np.ptp(healthy.op[-3600:]) < 0.01
    aggressive = simulate("aggressive-tuning")
    assert np.ptp(aggressive.op[-3600:]) > 5.0
    assert aggressive.op.max() < 100.0 and aggressive.op.min() > 0.0  # no saturation


def test_every_paper_scenario_exists() -> None:
    for name in ("table4-case1", "table4-case2", "table5-case1", "table5-case2", "table6",
                 "table7", "table9", "healthy", "aggressive-tuning", "disturbance"):
        assert name in SCENARIOS
    assert scenario("table6", tau=450.0).tau == 450.0
    assert scenario("table7", theta=35.0).theta == 35.0


@pytest.mark.parametrize(
    ("call", "name", "match"),
    [
        (lambda: scenario("nope"), "scenario", "`scenario` is unknown: 'nope'"),
        (lambda: scenario("table6", fs=-0.1), "fs", "`fs` must be >= 0"),
        (lambda: scenario("table6", fd=0.5), "fd", "`fd` must not exceed fs"),
        (lambda: scenario("table6", ts=0.0), "ts", "`ts` must be > 0"),
        (lambda: scenario("table6", bogus=1.0), "bogus", "`bogus` is not a scenario parameter"),
        (lambda: simulate("table6", duration=-1.0), "duration", "`duration` must be > 0"),
        (lambda: LoopBank(0, LoopParams(), HeValve(0, 0, 1)), "n", "`n` must be a positive"),
        (lambda: LoopBank(2, LoopParams(), HeValve(0, 0, 1), ts=-1.0), "ts", "`ts` must be > 0"),
        (lambda: LoopBank(2, LoopParams(tau=[1.0, 2.0, 3.0]), HeValve(0, 0, 1)), "tau",
         "must broadcast to 2 loops"),
    ],
)
def test_bad_parameters_raise_typed_error_naming_them(call, name: str, match: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=match) as info:
        call()
    assert info.value.name == name
