"""stiction.diagnosis.site: the site's feature statistics (running, merged, persisted),
CORAL towards the simulation's, label-shift EM and the Platt map."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stiction.diagnosis.site import SiteStats, coral, label_shift, platt


def _gauss(rng: np.random.Generator, n: int, mean: np.ndarray, mix: np.ndarray) -> np.ndarray:
    return mean + rng.standard_normal((n, mean.size)) @ mix


def test_running_statistics_equal_the_batch_ones() -> None:
    rng = np.random.default_rng(1)
    f = _gauss(rng, 300, np.arange(5.0), rng.standard_normal((5, 5)))
    run = SiteStats.empty(5)
    for row in f[:7]:
        run = run.update(row)  # one window at a time, as a gateway's rounds
    run = run.update(f[7:150]).merge(SiteStats.of(f[150:]))
    assert run.n == 300
    np.testing.assert_allclose(run.mean, f.mean(axis=0), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(run.cov, np.cov(f.T), rtol=1e-10, atol=1e-12)


def test_statistics_survive_the_state_file_and_refuse_garbage() -> None:
    rng = np.random.default_rng(2)
    s = SiteStats.of(rng.standard_normal((20, 3)))
    back = SiteStats.from_dict(json.loads(json.dumps(s.to_dict())))
    assert back.n == 20
    np.testing.assert_array_equal(back.mean, s.mean)
    np.testing.assert_array_equal(back.scatter, s.scatter)
    with pytest.raises(ValueError, match="site statistics"):
        SiteStats.from_dict({"n": 3, "mean": [0.0, 1.0], "scatter": [[1.0]]})
    with pytest.raises(ValueError, match="site statistics"):
        SiteStats.from_dict({"n": -1, "mean": [0.0], "scatter": [[1.0]]})


def test_coral_maps_a_shifted_site_onto_the_source() -> None:
    rng = np.random.default_rng(3)
    d = 6
    src_f = _gauss(rng, 4000, np.zeros(d), np.eye(d))
    mix = np.diag([3.0, 0.5, 2.0, 1.0, 0.3, 4.0]) + 0.4 * rng.standard_normal((d, d))
    site_f = _gauss(rng, 4000, np.linspace(-5, 5, d), mix)
    src, site = SiteStats.of(src_f), SiteStats.of(site_f)
    out = coral(site_f, site, src, prior=0.0, eps=0.0)
    np.testing.assert_allclose(out.mean(axis=0), src.mean, atol=1e-9)
    np.testing.assert_allclose(np.cov(out.T), src.cov, atol=1e-6)
    # per-feature standardisation: means and SDs, not the correlations
    diag = coral(site_f, site, src, prior=0.0, eps=0.0, diagonal=True)
    np.testing.assert_allclose(diag.std(axis=0, ddof=1), np.sqrt(np.diag(src.cov)), rtol=1e-9)


def test_coral_leaves_the_source_alone_and_moves_little_on_few_windows() -> None:
    rng = np.random.default_rng(4)
    src_f = rng.standard_normal((2000, 4))
    src = SiteStats.of(src_f)
    np.testing.assert_allclose(coral(src_f, src, src, prior=0.0), src_f, atol=1e-9)
    one = np.full(4, 10.0)  # one window far out: a single file is not a site
    alone = coral(one, SiteStats.of(one[None]), src)
    assert np.all(alone > 8.0)  # moved towards the source by 1/17 of the way at most
    assert np.array_equal(coral(one, SiteStats.empty(4), src), one)  # no site: as it is


def test_label_shift_finds_the_sites_share_of_sticky_windows() -> None:
    rng = np.random.default_rng(5)
    # a score calibrated where 20 % stick: logit = x with x ~ N(+-1.5, 1) and prior 0.2
    def posterior(x: np.ndarray, prior: float) -> np.ndarray:
        lr = np.exp(3.0 * x)  # N(1.5,1) / N(-1.5,1)
        return prior * lr / (prior * lr + 1 - prior)

    y = rng.random(5000) < 0.7  # the site: 70 % sticky
    x = np.where(y, rng.normal(1.5, 1.0, y.size), rng.normal(-1.5, 1.0, y.size))
    q, share = label_shift(posterior(x, 0.2), 0.2)
    assert share == pytest.approx(0.7, abs=0.03)
    np.testing.assert_allclose(q, posterior(x, share), atol=1e-9)
    _, same = label_shift(posterior(np.where(rng.random(5000) < 0.2, rng.normal(1.5, 1, 5000),
                                             rng.normal(-1.5, 1, 5000)), 0.2), 0.2)
    assert same == pytest.approx(0.2, abs=0.03)
    with pytest.raises(ValueError, match="source_prior"):
        label_shift([0.5], 1.0)


def test_platt_is_a_sigmoid_of_a_scaled_logit() -> None:
    assert float(platt(0.0, 2.0, 0.0)) == 0.5
    assert float(platt(1.0, 2.0, -2.0)) == 0.5
    assert float(platt(1000.0, 1.0, 0.0)) == pytest.approx(1.0)


def test_label_shift_on_few_windows_stays_near_the_source_share() -> None:
    high = np.full(3, 0.99)  # three confident windows: not yet a site full of sticky valves
    _, free = label_shift(high, 0.2)
    _, held = label_shift(high, 0.2, prior_weight=20.0)
    assert free > 0.95 and 0.2 < held < 0.4
    q, none = label_shift(np.empty(0), 0.2, prior_weight=20.0)
    assert none == pytest.approx(0.2) and q.size == 0
