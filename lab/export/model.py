"""The fitted decision as stiction/diagnosis/model.json: the trees as arrays that
``stiction.diagnosis.model`` runs in numpy, with the thresholds and how they were made,
checked against scikit-learn's own predictions before anything is written."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

import stiction
from stiction.diagnosis.features import NAMES
from stiction.diagnosis.model import Model

from ..training.fit import Fitted

MODEL = Path(stiction.__file__).resolve().parent / "diagnosis" / "model.json"
BY = "python -m lab train --write (lab/)"
CHECKED = 500  # windows on which the export must give scikit-learn's probabilities


def export(clf: Any, hi: float, lo: float, meta: dict[str, Any]) -> dict[str, Any]:
    """The fitted trees as model.json's arrays (internal nodes: the count-weighted mean of
    their leaves, on the leaves' scale, for the contributions)."""
    trees = []
    for (pred,) in clf._predictors:
        nodes = pred.nodes
        value = nodes["value"].astype(float).copy()
        count = nodes["count"].astype(float)
        for i in sorted(range(len(nodes)), key=lambda k: -int(nodes["depth"][k])):
            if not nodes["is_leaf"][i]:
                a, b = int(nodes["left"][i]), int(nodes["right"][i])
                value[i] = (value[a] * count[a] + value[b] * count[b]) / (count[a] + count[b])
        leaf = nodes["is_leaf"].astype(bool)
        trees.append({
            "feature": np.where(leaf, -1, nodes["feature_idx"]).astype(int).tolist(),
            # exact: a training value equal to a threshold goes left, as in the fit
            "threshold": [float(v) for v in nodes["num_threshold"]],
            "missing_left": nodes["missing_go_to_left"].astype(int).tolist(),
            "left": nodes["left"].astype(int).tolist(),
            "right": nodes["right"].astype(int).tolist(),
            "value": [float(v) for v in value]})
    return {"kind": "boosted trees", "features": list(NAMES), "trees": trees,
            "baseline": float(np.ravel(clf._baseline_prediction)[0]), "stiction_at": hi,
            "no_stiction_at": lo, "meta": meta}


def model_data(fitted: Fitted) -> dict[str, Any]:
    """model.json's content for ``fitted``; raises AssertionError when the exported trees
    and scikit-learn disagree on the first :data:`CHECKED` training windows."""
    meta = {"setting": fitted.setting, "windows": len(fitted.y), "sticky": int(fitted.y.sum()),
            "worst_fold_found": round(fitted.worst, 3), "trained": time.strftime("%Y-%m-%d"),
            "by": BY}
    data = export(fitted.clf, fitted.stiction_at, fitted.no_stiction_at, meta)
    model = Model.from_dict(data)
    mine = np.array([model.probability(v) for v in fitted.x[:CHECKED]])
    theirs = fitted.clf.predict_proba(fitted.x[:CHECKED])[:, 1]
    assert np.allclose(mine, theirs, atol=1e-6), float(np.abs(mine - theirs).max())
    return data


def write(data: dict[str, Any], path: Path = MODEL) -> None:
    path.write_text(json.dumps(data, separators=(",", ":")) + "\n")
