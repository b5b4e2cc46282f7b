"""stiction.diagnosis.shape: the shipped network in numpy equals the training library's
output (PyTorch, written into shape_fixture.npz at export) to 1e-6 on 100 windows; its input
is cut and read as documented; its score does not depend on signs, offsets or scales."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stiction.diagnosis import shape

FIXTURE = Path(__file__).with_name("shape_fixture.npz")


def _fixture() -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray, np.ndarray]:
    with np.load(FIXTURE) as d:
        ends = np.cumsum(d["lengths"])[:-1]
        op = np.split(d["op"].astype(np.float64), ends)
        pv = np.split(d["pv"].astype(np.float64), ends)
        return list(zip(op, pv, strict=True)), d["periods"], d["scores"]


def test_numpy_equals_the_training_library_on_100_windows() -> None:
    windows, periods, want = _fixture()
    assert len(windows) == 100
    got = np.array([shape.score(op, pv, period=None if np.isnan(p) else float(p),
                                find=False).score for (op, pv), p in zip(windows, periods,
                                                                         strict=True)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    assert np.ptp(want) > 0.5  # the windows span the scores, not one corner of them


def test_the_shipped_weights_are_small_and_say_how_they_were_made() -> None:
    net = shape.load()
    assert 1_000 <= net.n_weights <= 50_000
    assert shape.WEIGHTS.stat().st_size < 300_000
    assert {"platt", "threshold", "trained_windows"} <= set(net.meta)
    back = shape.from_arrays(shape.to_arrays(net))
    for a, b in zip(back.members, net.members, strict=True):
        for (w1, b1), (w2, b2) in zip((*a.convs, a.dense, a.last), (*b.convs, b.dense, b.last),
                                      strict=True):
            assert np.array_equal(w1, w2) and np.array_equal(b1, b2)


def test_spans_cover_the_cycles_or_the_window() -> None:
    kw = {"cycles": 6.0, "crops": 4, "span_without_cycle": 1024}
    assert shape.spans(3600, 100.0, **kw) == [(0, 600), (1000, 1600), (2000, 2600),
                                               (3000, 3600)]
    assert shape.spans(1000, 100.0, **kw) == [(200, 800)]  # one span fits: the middle
    assert shape.spans(500, 100.0, **kw) == [(0, 500)]  # fewer cycles than six: all of it
    assert shape.spans(3000, None, **kw) == [(0, 1024), (1976, 3000)]
    assert shape.spans(751, None, **kw) == [(0, 751)]


def test_inputs_are_resampled_detrended_and_standardised() -> None:
    t = np.arange(900.0)
    op = 0.05 * t + np.sin(2 * np.pi * t / 150)  # a ramp under the cycle
    x = shape.inputs(op, 3 * op + 7, 150.0, length=256, cycles=6.0, crops=1)
    assert x.shape == (1, 2, 256)
    np.testing.assert_allclose(x[0, 0], x[0, 1], atol=1e-9)  # offset and scale gone
    assert abs(x[0, 0].mean()) < 1e-9 and abs(x[0, 0].std() - 1.0) < 1e-9
    lin = np.polyfit(np.arange(256), x[0, 0], 1)
    assert abs(lin[0]) < 1e-9  # no line left
    flat = shape.inputs(np.full(300, 4.0), np.arange(300.0), None)
    assert np.all(flat[0, 0] == 0.0)  # a flat OP reads as zeros, not as noise blown up


def test_the_score_ignores_signs_offsets_and_scales() -> None:
    rng = np.random.default_rng(8)
    t = np.arange(5000.0)
    op = np.cumsum(rng.standard_normal(5000)) * 0.1 + 3 * (t % 200) / 200
    pv = np.round(np.sin(2 * np.pi * t / 200) * 3) + 0.2 * rng.standard_normal(5000)
    base = shape.score(op, pv, period=200.0)
    assert 0.0 <= base.score <= 1.0 and base.spans == shape.load().crops == 2
    for a, b, c, d in ((-1.0, 0.0, 1.0, 0.0), (1.0, 0.0, -1.0, 0.0), (-1.0, 5.0, -1.0, 0.0),
                       (250.0, -40.0, 0.01, 1e4)):
        other = shape.score(a * op + b, c * pv + d, period=200.0)
        assert other.logit == pytest.approx(base.logit, abs=1e-7)
    assert shape.score(op, pv).period is not None  # the cycle looked up when not given
    assert shape.score(op, pv, find=False).period is None


def test_the_shipped_network_tells_stick_slip_from_a_loop_ringing_from_its_tuning() -> None:
    from stiction.scenarios.named import scenario, simulate  # noqa: PLC0415

    net = shape.load()
    threshold = net.meta["threshold"]
    assert isinstance(threshold, float)
    for name, sticky in (("table4-case1", True), ("table5-case1", True),
                         ("aggressive-tuning", False)):
        r = simulate(scenario(name), noise=0.1, seed=0)
        s = shape.score(r.op[-3600:], r.pv[-3600:])
        assert s.readable
        p = float(shape.calibrated(net, s.logit))
        if sticky:  # scores 0.98-1.00 on seeds 0-2
            assert s.score > 0.9 and p > threshold, (name, s)
        else:  # 0.31-0.32
            assert s.score < 0.5 and p < threshold, (name, s)


def test_a_cycle_of_a_few_samples_is_not_readable() -> None:
    t = np.arange(2000.0)
    fast = shape.score(np.sin(2 * np.pi * t / 4), np.cos(2 * np.pi * t / 4), period=4.0)
    assert not fast.readable
    assert shape.score(np.sin(t / 30), np.cos(t / 30), period=188.5).readable


def test_a_site_moves_the_probabilities_by_its_share_of_sticky_windows() -> None:
    net = shape.load()
    mostly_sticky = np.r_[np.full(30, 3.0), np.full(10, -3.0)]
    mostly_good = np.r_[np.full(2, 3.0), np.full(38, -3.0)]
    p_sticky, share_sticky = shape.at_site(net, mostly_sticky)
    p_good, share_good = shape.at_site(net, mostly_good)
    assert share_sticky > 0.5 and share_good < 0.15
    assert p_sticky[0] > float(shape.calibrated(net, 3.0)) > p_good[0]
