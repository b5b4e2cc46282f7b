"""The shape corpus's machinery (lab/shape/) without the built corpus: the historian, the
valves, the twin run, the labels, the real residuals' source, the figures; and, where torch
is installed, the shipped network recomputed by the training library."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from deploy_support import require

from lab.shape import draws, historian, loads, metrics, simulate
from lab.shape.valves import LaggedValve, MixedValve
from stiction.models.valves import HeValve, KanoValve


# ------------------------------------------------------------------------- the historian
def test_sampling_takes_the_last_value_or_the_intervals_mean() -> None:
    x = np.arange(12.0)
    assert historian.sample(x, 4, averaged=False).tolist() == [3.0, 7.0, 11.0]
    assert historian.sample(x, 4, averaged=True).tolist() == [1.5, 5.5, 9.5]


def test_swinging_door_replay_stays_within_its_deviation() -> None:
    rng = np.random.default_rng(0)
    x = np.cumsum(0.02 * rng.standard_normal(3000)) + 5 * np.sin(np.arange(3000) / 40)
    for dev in (0.1, 0.5, 2.0):
        kept = historian.swinging_door(x, dev)
        replay = historian.compress(x, "swinging-door", dev)
        assert kept.size < x.size / 2
        err = np.abs(replay - x)
        # each kept point within the doors: the replay stays near, not exactly within dev
        assert float(np.mean(err)) <= dev and float(np.max(err)) <= 3 * dev


def test_deadband_keeps_a_value_only_past_the_band() -> None:
    x = np.array([0.0, 0.2, 0.4, 0.6, 1.3, 1.2, 0.2, 0.25])
    assert historian.deadband(x, 0.5).tolist() == [0, 3, 4, 6, 7]
    t = np.arange(x.size, dtype=float)
    assert np.allclose(historian.compress(x, "deadband", 0.5),
                       np.interp(t, [0, 3, 4, 6, 7], x[[0, 3, 4, 6, 7]]))


# ----------------------------------------------------------------------------- the valves
def test_mixed_valve_steps_each_model_on_its_own_loops() -> None:
    he, kano = HeValve(np.array([0.02, 0.05]), np.array([0.01, 0.0]), 1.0), \
        KanoValve(np.array([0.04]), np.array([0.01]))
    mixed = MixedValve(3, [(np.array([0, 2]), he), (np.array([1]), kano)])
    u = 0.5 + 0.1 * np.sin(np.arange(200) / 9.0)
    s, sh, sk = mixed.initial_state(0.5), he.initial_state(np.full(2, 0.5)), \
        kano.initial_state(np.full(1, 0.5))
    for v in u:
        s, sh, sk = mixed.step(s, v), he.step(sh, v), kano.step(sk, v)
        assert np.array_equal(mixed.position(s)[[0, 2]], he.position(sh))
        assert np.array_equal(mixed.position(s)[[1]], kano.position(sk))
    with pytest.raises(ValueError, match="exactly one group"):
        MixedValve(3, [(np.array([0, 1]), he)])


def test_lags_after_the_valve_pass_through_at_zero_and_lag_otherwise() -> None:
    he = HeValve(np.zeros(2), np.zeros(2), 1.0)
    lagged = LaggedValve(he, np.array([[0.0, 10.0], [0.0, 0.0]]))
    s = lagged.initial_state(0.0)
    s = lagged.step(s, 1.0)
    assert lagged.position(s)[0] == 1.0
    assert lagged.position(s)[1] == pytest.approx(1.0 - np.exp(-0.1))


# ----------------------------------------------------------------------------- the twins
def test_a_loop_without_friction_is_its_twin_sample_for_sample(monkeypatch) -> None:
    """Loads, noise and setpoints are shared: with the friction taken away, the 'sticky'
    run and its twin are the same run."""
    def frictionless(seed: int, index: int) -> draws.Loop:
        loop = draws.draw(seed, index)
        return dataclasses.replace(loop, fs=0.0, fd=0.0, k=1.0)

    require(loads.FACTORY.exists(), f"{loads.FACTORY} not found (../shared/data)")
    monkeypatch.setattr(simulate, "draw", frictionless)
    monkeypatch.setattr(simulate, "STEPS", 2000)
    monkeypatch.setattr(simulate, "WARM", 200)
    _, op, pv, _, _, _ = simulate.run(7, 4)
    assert np.array_equal(op[:4], op[4:]) and np.array_equal(pv[:4], pv[4:])
    assert np.all(np.std(pv, axis=1) > 0)  # and they do move


def test_sticky_runs_are_labelled_by_what_the_valve_changed() -> None:
    loop = draws.draw(0, 0)
    assert simulate.label(loop, slips=2, r_pv=0.6, r_op=0.0) == "stiction"
    assert simulate.label(loop, slips=1, r_pv=5.0, r_op=5.0) == "ambiguous"  # never slipped
    assert simulate.label(loop, slips=50, r_pv=0.3, r_op=0.3) == "ambiguous"
    assert simulate.label(loop, slips=50, r_pv=0.05, r_op=0.05) == "invisible"


def test_draws_are_seeded_and_loops_tuned_below_their_ultimate_gain() -> None:
    a, b = draws.draw(3, 5), draws.draw(3, 5)
    assert a == b and draws.draw(3, 6) != a
    for i in range(40):
        loop = draws.draw(11, i)
        assert 0 < loop.kc <= 0.9 * draws.ultimate_gain(loop, loop.ti) + 1e-12
        assert loop.samples * loop.interval <= draws.STEPS
        assert loop.samples >= min(300, draws.STEPS // loop.interval)


def test_real_residuals_come_from_the_unlabelled_factory_loops_only() -> None:
    assert loads.FACTORY.name == "unlabelled-factory"
    require(loads.FACTORY.exists(), f"{loads.FACTORY} not found (../shared/data)")
    lib = loads.residuals()
    assert len(lib) == 4 and all(x.size == 10_080 and np.all(np.isfinite(x)) for x in lib)
    y = loads.replay(np.random.default_rng(1), 5000)
    assert y.size == 5000 and abs(float(np.std(y)) - 1.0) < 1e-9


# ----------------------------------------------------------------------------- figures
def test_auc_and_calls() -> None:
    s = np.array([0.9, 0.8, 0.8, 0.3, 0.2, 0.1])
    y = np.array([1, 1, 0, 1, 0, 0])
    assert metrics.auc(s, y) == pytest.approx((3 + 2.5 + 2) / 9)  # ties count half
    assert metrics.calls(s, y, 0.8) == (2, 3, 1, 3)
    w = metrics.group_weights(["a", "a", "b", "c", "c", "c"])
    assert w.tolist() == [0.5, 0.5, 1.0, 1 / 3, 1 / 3, 1 / 3]
    assert metrics.group_calls(s, y, ["a", "a", "b", "c", "d", "d"], 0.5) == (1, 2, 1, 2)
    assert metrics.threshold_for_precision(s, y, 0.7) == 0.3  # 3 of 4 calls right
    assert metrics.threshold_for_precision(s, y, 0.9) == 0.9  # at 0.8 the tie: 2 of 3


# ------------------------------------------------------------ the shipped network in torch
def test_the_shipped_network_recomputed_by_torch_equals_numpy_and_the_fixture() -> None:
    pytest.importorskip("torch")
    from lab.shape import data, export, net  # noqa: PLC0415 (torch: the bench extra)
    from stiction.diagnosis import shape  # noqa: PLC0415

    nw = shape.load()
    first = nw.members[0]
    arch = net.Arch(tuple(w.shape[0] for w, _ in first.convs),
                    tuple(w.shape[2] for w, _ in first.convs), first.dense[0].shape[0])
    models = [export.torch_model(m, arch) for m in nw.members]
    cfg = data.Config(nw.length, nw.cycles, nw.crops, nw.span_without_cycle)
    with np.load(export.FIXTURE) as d:
        ends = np.cumsum(d["lengths"])[:-1]
        windows = list(zip(np.split(d["op"], ends), np.split(d["pv"], ends), strict=True))
        periods, want = d["periods"], d["scores"]
    got_periods, z = export.torch_scores(models, cfg, windows)
    np.testing.assert_array_equal(got_periods, periods)  # the cycles as exported
    np.testing.assert_allclose(metrics.sigmoid(z), want, rtol=0, atol=1e-6)
    numpy = [shape.score(o.astype(np.float64), v.astype(np.float64), period=None if
                         np.isnan(q) else float(q), find=False).score
             for (o, v), q in zip(windows, periods, strict=True)]
    np.testing.assert_allclose(numpy, metrics.sigmoid(z), rtol=0, atol=1e-6)
