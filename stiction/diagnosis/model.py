"""The learned decision: one probability of stiction from a window's features.

A boosted ensemble of shallow regression trees over the features of :mod:`.features`
(log-odds ``baseline + sum of the trees' leaves``, then the logistic link), fitted by
``python -m bench.train --write`` on the development corpus, validated leave one source out
(docs/accuracy.md). Its parameters ship as data, ``model.json`` beside this module, and run
in numpy: every tree is walked at once, one level per step. A missing feature (NaN: a test
that did not run) goes the way the fit sent missing values at each split.

The same file carries the two thresholds the held-out folds chose: ``stiction`` at or above
``stiction_at`` (the score whose held-out calls have the best F0.5, precision counting twice
as much as what is found: 0.87 today, where 78 % of the held-out calls were sticky),
``no_stiction`` at or below ``no_stiction_at`` (under it at most 2 % of the held-out windows
were sticky); in between the model cannot tell: ``undetermined``.

:meth:`Model.contributions` says what decided: along each tree's path, every split moves the
prediction from the node's value to the child's; that move is credited to the split's
feature (Saabas 2014), and the features are summed by test.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import math
from importlib import resources
from typing import Any

import numpy as np

from .._validate import FloatArray
from .features import NAMES, TEST_OF

__all__ = ["Model", "load"]


@dataclasses.dataclass(frozen=True)
class Model:
    """Trees as arrays (trees x nodes, padded); node 0 is each tree's root."""

    feature: np.ndarray  # the split's feature index (NAMES order), -1 at a leaf
    threshold: FloatArray  # go left when the feature <= threshold
    missing_left: np.ndarray  # a NaN feature goes left
    left: np.ndarray
    right: np.ndarray
    value: FloatArray  # the node's log-odds contribution (leaves: what the tree adds)
    baseline: float
    stiction_at: float
    no_stiction_at: float
    meta: dict[str, Any] = dataclasses.field(default_factory=dict)

    def _paths(self, x: FloatArray) -> list[np.ndarray]:
        """Each level's node of every tree, root first."""
        rows = np.arange(self.feature.shape[0])
        node = np.zeros(rows.size, dtype=np.intp)
        path = [node]
        for _ in range(self.feature.shape[1]):
            f = self.feature[rows, node]
            inner = f >= 0
            if not inner.any():
                break
            v = x[np.where(inner, f, 0)]
            go_left = np.where(np.isnan(v), self.missing_left[rows, node],
                               v <= self.threshold[rows, node])
            node = np.where(inner, np.where(go_left, self.left[rows, node],
                                            self.right[rows, node]), node)
            path.append(node)
        return path

    def score(self, x: FloatArray) -> float:
        """The log-odds of stiction."""
        leaf = self._paths(x)[-1]
        return self.baseline + float(self.value[np.arange(leaf.size), leaf].sum())

    def probability(self, x: FloatArray) -> float:
        z = self.score(x)
        return 1.0 / (1.0 + math.exp(-z)) if z > -700 else 0.0

    def contributions(self, x: FloatArray) -> dict[str, float]:
        """Each test's share of the log-odds beyond the trees' roots (module doc)."""
        rows = np.arange(self.feature.shape[0])
        path = self._paths(x)
        out: dict[str, float] = {}
        for parent, child in itertools.pairwise(path):
            moved = child != parent
            if not moved.any():
                continue
            delta = self.value[rows, child] - self.value[rows, parent]
            for f, d in zip(self.feature[rows, parent][moved], delta[moved], strict=True):
                test = TEST_OF[NAMES[int(f)]]
                out[test] = out.get(test, 0.0) + float(d)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Model:
        """From ``model.json``; a feature this code does not compute is an error (the model
        would read the wrong column)."""
        names = list(data["features"])
        unknown = set(names) - set(NAMES)
        if unknown:
            raise ValueError(f"model.json names features this code does not compute: "
                             f"{sorted(unknown)}")
        remap = np.array([NAMES.index(n) for n in names] + [-1])
        trees = data["trees"]
        width = max(len(t["feature"]) for t in trees)

        def pad(key: str, fill: float, dtype: Any) -> np.ndarray:
            return np.array([list(t[key]) + [fill] * (width - len(t[key])) for t in trees],
                            dtype=dtype)

        feature = pad("feature", -1, np.intp)
        return cls(np.where(feature >= 0, remap[feature], -1), pad("threshold", 0.0, float),
                   pad("missing_left", 0, bool), pad("left", 0, np.intp),
                   pad("right", 0, np.intp), pad("value", 0.0, float), float(data["baseline"]),
                   float(data["stiction_at"]), float(data["no_stiction_at"]),
                   dict(data.get("meta", {})))


@functools.cache
def load() -> Model:
    """The shipped model (``model.json`` beside this module)."""
    text = resources.files(__package__).joinpath("model.json").read_text(encoding="utf-8")
    return Model.from_dict(json.loads(text))
