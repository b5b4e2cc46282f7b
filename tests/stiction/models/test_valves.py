"""Valve models: He semiphysical, physical Kayihan-Doyle, Choudhury, Kano."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiction import (
    ChoudhuryValve,
    HeValve,
    KanoValve,
    ParameterError,
    PhysicalParams,
    PhysicalValve,
    k_from_physical,
)


def run(model, u):  # type: ignore[no-untyped-def]
    state = model.initial_state(np.asarray(u[0], dtype=float))
    out = []
    for ui in u:
        state = model.step(state, ui)
        out.append(np.array(model.position(state), copy=True))
    return np.array(out)


def test_k_from_table1_is_1_99() -> None:
    p = PhysicalParams()
    assert k_from_physical(p.m, p.k, p.fv) == pytest.approx(1.99, abs=0.005)
    fs, fd, k = p.normalised()
    assert fs == pytest.approx(1708 / (5.25e4 * 0.1016))
    assert fd == pytest.approx(1423 / (5.25e4 * 0.1016))
    assert k == pytest.approx(1.9907, abs=1e-4)


def test_k_is_one_without_overshoot() -> None:
    assert k_from_physical(1.0, 1.0, 2.0) == 1.0  # critically damped
    assert k_from_physical(1.0, 1.0, 0.0) == pytest.approx(2.0)


def test_he_valve_sticks_then_jumps_with_overshoot() -> None:
    valve = HeValve(fs=0.3, fd=0.27, k=2.0)
    s = valve.initial_state(0.5)
    s = valve.step(s, 0.5 + 0.299)  # |e| below fs: stays
    assert float(s.x) == 0.5
    s = valve.step(s, 0.5 + 0.31)  # slips by K(e - fd) = 2 * 0.04
    assert float(s.x) == pytest.approx(0.5 + 2 * (0.31 - 0.27))
    # reversing needs e < -fs: moving back by less than fs + (x - u) stays put
    x1 = float(s.x)
    s = valve.step(s, x1 - 0.29)
    assert float(s.x) == x1


def test_he_original_model_k1_lands_fd_behind_input() -> None:
    valve = HeValve(fs=0.1, fd=0.05, k=1.0)
    s = valve.step(valve.initial_state(0.0), 0.2)
    assert float(s.x) == pytest.approx(0.2 - 0.05)


def test_he_perfect_valve_follows_input() -> None:
    u = np.sin(np.linspace(0, 10, 200))
    x = run(HeValve(0.0, 0.0, 1.0), u)
    np.testing.assert_allclose(x, u)


def test_he_vectorised_equals_scalar_loop() -> None:
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(0, 0.02, size=(300, 5)), axis=0)
    fs = np.array([0.0, 0.05, 0.1, 0.2, 0.3])
    fd = fs * 0.8
    many = run(HeValve(fs, fd, 1.99), u)
    for i in range(5):
        one = run(HeValve(float(fs[i]), float(fd[i]), 1.99), u[:, i])
        np.testing.assert_array_equal(many[:, i], one)


@pytest.mark.parametrize(
    ("kwargs", "name", "match"),
    [
        ({"fs": -0.1, "fd": 0.0}, "fs", "`fs` must be >= 0"),
        ({"fs": 0.1, "fd": 0.2}, "fd", "`fd` must not exceed fs"),
        ({"fs": 0.1, "fd": 0.05, "k": 2.5}, "k", "`k` must lie in"),
        ({"fs": float("nan"), "fd": 0.0}, "fs", "`fs` must be finite"),
    ],
)
def test_he_valve_rejects_bad_parameters(kwargs: dict[str, float], name: str, match: str) -> None:
    with pytest.raises(ParameterError, match=match) as info:
        HeValve(**kwargs)
    assert info.value.name == name
    assert isinstance(info.value, ValueError)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    fs=st.floats(0.0, 0.4),
    ratio=st.floats(0.0, 1.0),
    k=st.floats(1.0, 2.0),
    steps=st.lists(st.floats(-0.05, 0.05), min_size=5, max_size=80),
)
def test_he_valve_invariants(fs: float, ratio: float, k: float, steps: list[float]) -> None:
    """After any step the net force |u - x| is at most max(fs, |fd - (K-1)(e - fd)|)-bounded:
    a stuck valve keeps |e| <= fs, a slipping one lands on the far side by less than fs."""
    fd = fs * ratio
    valve = HeValve(fs, fd, k)
    u = 0.5 + np.cumsum(steps)
    s = valve.initial_state(0.5)
    for ui in u:
        x_prev = float(s.x)
        s = valve.step(s, ui)
        e = ui - x_prev
        if abs(e) <= fs:
            assert float(s.x) == x_prev
        else:
            assert float(s.x) == pytest.approx(x_prev + k * (e - math.copysign(fd, e)))
            assert abs(ui - float(s.x)) <= abs(e) + 1e-12


def test_physical_valve_sticks_until_breakaway_force() -> None:
    p = PhysicalParams()
    valve = PhysicalValve(p)
    s = valve.initial_state(0.0)
    # net force just below Fs: no motion
    u_hold = (p.fs * 0.999) / p.sa
    s = valve.step(s, u_hold)
    assert float(s.x) == 0.0
    assert not bool(s.moving)
    # just above Fs: breaks away and comes to rest with overshoot K(e - fd)
    u_go = (p.fs * 1.001) / p.sa
    s = valve.step(s, u_go)
    assert not bool(s.moving)
    _, fd, k = p.normalised()
    e = u_go * p.sa / (p.k * p.xm)
    assert float(s.x) / p.xm == pytest.approx(k * (e - fd), rel=1e-3)


def test_physical_valve_vectorised() -> None:
    p = PhysicalParams()
    valve = PhysicalValve(p)
    pressures = np.array([0.0, 0.5, 1.0]) * p.fs * 2 / p.sa
    s = valve.step(valve.initial_state(np.zeros(3)), pressures)
    for i, pa in enumerate(pressures):
        one = valve.step(valve.initial_state(0.0), pa)
        assert float(s.x[i]) == pytest.approx(float(one.x), abs=1e-12)


def test_physical_params_validation() -> None:
    with pytest.raises(ParameterError, match="`fc` must not exceed fs"):
        PhysicalParams(fc=2000.0, fs=1000.0)
    with pytest.raises(ParameterError, match="`m` must be > 0"):
        PhysicalParams(m=0.0)


@pytest.mark.parametrize("cls", [ChoudhuryValve, KanoValve])
def test_two_parameter_models_deadband_and_jump(cls: type) -> None:
    s_, j_ = 0.10, 0.04
    valve = cls(s=s_, j=j_)
    up = np.linspace(0.5, 0.8, 31)  # rising input: valve moves, lagging by (S - J)/2
    down = np.linspace(0.8, 0.6, 21)[1:]
    u = np.concatenate([up, down])
    x = run(valve, u)
    # once moving, the valve lags the rising input by (S - J)/2
    np.testing.assert_allclose(x[15:31], u[15:31] - (s_ - j_) / 2, atol=1e-12)
    # reversal: stuck until the input has come back by more than S
    after = x[31:]
    stuck = after == x[30]
    u_back = 0.8 - down
    assert stuck[u_back <= s_ - 1e-9].all()
    assert not stuck[u_back > s_ + 0.011].any()
    # when it slips it jumps: first move is larger than the input step
    first = int(np.argmin(stuck))
    assert abs(after[first] - x[30]) >= j_


@pytest.mark.parametrize("cls", [ChoudhuryValve, KanoValve])
def test_two_parameter_models_linear_without_friction(cls: type) -> None:
    u = 0.5 + 0.2 * np.sin(np.linspace(0, 12, 300))
    x = run(cls(s=0.0, j=0.0), u)
    np.testing.assert_allclose(x[1:], u[1:], atol=1e-12)


@pytest.mark.parametrize("cls", [ChoudhuryValve, KanoValve])
def test_two_parameter_models_validate(cls: type) -> None:
    with pytest.raises(ParameterError, match="`j` must not exceed s"):
        cls(s=0.01, j=0.02)
    with pytest.raises(ParameterError, match="`s` must be >= 0"):
        cls(s=-0.01, j=0.0)
