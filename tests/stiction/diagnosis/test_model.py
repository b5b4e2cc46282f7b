"""The learned decision (stiction.diagnosis.model, .features): the trees evaluated in numpy
as the fit built them, what decided summed by test, the shipped file's integrity, and
features without units."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stiction.diagnosis.analyze import analyze_details
from stiction.diagnosis.features import NAMES, TEST_OF, features
from stiction.diagnosis.model import Model, load
from stiction.scenarios.named import scenario, simulate


def _toy() -> Model:
    """Two stumps: on ``kano.index`` (missing goes right) and on ``horch.vote``."""
    def stump(feature: str, threshold: float, missing_left: int, lo: float, hi: float
              ) -> dict[str, list[float] | list[int]]:
        return {"feature": [NAMES.index(feature), -1, -1], "threshold": [threshold, 0, 0],
                "missing_left": [missing_left, 0, 0], "left": [1, 0, 0],
                "right": [2, 0, 0], "value": [(lo + hi) / 2, lo, hi]}
    return Model.from_dict({"features": list(NAMES), "baseline": -0.5, "stiction_at": 0.8,
                            "no_stiction_at": 0.3,
                            "trees": [stump("kano.index", 0.5, 0, -1.0, 2.0),
                                      stump("horch.vote", 0.0, 1, -0.5, 0.5)]})


def test_trees_walk_as_fitted_missing_values_included() -> None:
    m = _toy()
    x = np.full(len(NAMES), np.nan)
    x[NAMES.index("kano.index")] = 0.9  # right: +2
    x[NAMES.index("horch.vote")] = 1.0  # right: +0.5
    assert m.score(x) == pytest.approx(-0.5 + 2.0 + 0.5)
    assert m.probability(x) == pytest.approx(1 / (1 + math.exp(-2.0)))
    x[NAMES.index("kano.index")] = np.nan  # missing goes right here
    x[NAMES.index("horch.vote")] = np.nan  # and left here
    assert m.score(x) == pytest.approx(-0.5 + 2.0 - 0.5)


def test_contributions_are_the_moves_from_the_roots_credited_to_their_tests() -> None:
    m = _toy()
    x = np.full(len(NAMES), np.nan)
    x[NAMES.index("kano.index")] = 0.1
    x[NAMES.index("horch.vote")] = -1.0
    parts = m.contributions(x)
    assert parts == pytest.approx({"kano": -1.0 - 0.5, "horch": -0.5 - 0.0})
    roots = float(m.value[:, 0].sum())
    assert sum(parts.values()) == pytest.approx(m.score(x) - m.baseline - roots)


def test_a_model_naming_a_feature_this_code_lacks_is_refused() -> None:
    with pytest.raises(ValueError, match="does not compute"):
        Model.from_dict({"features": ["no.such"], "baseline": 0, "stiction_at": 0.9,
                         "no_stiction_at": 0.1, "trees": [{"feature": [0, -1, -1],
                         "threshold": [0, 0, 0], "missing_left": [0, 0, 0],
                         "left": [1, 0, 0], "right": [2, 0, 0], "value": [0, 0, 0]}]})


def test_the_shipped_model_is_whole_and_its_thresholds_ordered() -> None:
    m = load()
    assert 0.0 < m.no_stiction_at < m.stiction_at < 1.0
    assert m.feature.shape[0] >= 50 and (m.feature < len(NAMES)).all()
    assert m.meta["windows"] > 10_000  # fitted on the corpus, not a handful of records
    assert set(TEST_OF.values()) >= {"kano", "hammerstein", "cycle", "shape"}


def _window(scale: float, offset: float) -> np.ndarray:
    rec = simulate(scenario("table4-case2"), noise=0.02, seed=3)
    pv = rec.pv if scale == 1.0 else rec.pv * 0.5 - 2.0
    d = analyze_details(rec.op * scale + offset, pv, ts=1.0)
    assert d.findings is not None and d.cycle is not None
    assert d.op is not None and d.pv is not None
    return features(d.findings.evidence, d.findings.results, d.cycle, op=d.op, pv=d.pv,
                    integrating=False)


def test_features_have_no_units() -> None:
    """OP in other units and PV in other units: the same features (the decision must not
    learn one plant's units), and on a sticky loop the shipped model says stiction."""
    a, b = _window(1.0, 0.0), _window(4.0, 10.0)
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9, equal_nan=True,
                               err_msg=str([n for n, u, v in zip(NAMES, a, b, strict=True)
                                            if not np.isclose(u, v, equal_nan=True)]))
    assert load().probability(a) >= load().stiction_at
