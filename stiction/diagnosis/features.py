"""What the decision reads of one window: every test's vote and value, the numbers behind
them, what the gates measured and the shape of OP and PV, as one vector (:func:`features`,
names in :data:`NAMES`; NaN where a number does not exist for the window).

Only numbers without units: a share, a ratio, a kurtosis, a phase, a count of samples or
cycles, never an amount of OP or PV (a size in OP units that tells sticky from good on one
plant's units tells nothing on the next one's). The tests' results are read through the
fields their classes document (:mod:`stiction.detectors`); a test the registry gains has
no feature here until a model is trained with it: it is reported in the evidence and
weighs nothing.

The shape: OP and PV averaged over blocks of a twentieth of the cycle, the kurtosis of each
(a square wave 1, a sine 1.5, noise 3) and of its increments (jumps make them heavy-tailed).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._assessment import Evidence
from .._validate import FloatArray
from ..signal.cycle import Cycle

__all__ = ["NAMES", "TEST_OF", "features"]

_TESTS = ("si_op", "si_pv", "bicoherence", "horch", "ellipse", "kano", "stick_slip",
          "hammerstein", "fast_cycle")
_FIELDS: dict[str, tuple[str, ...]] = {  # unit-free numbers behind each test's evidence
    "bicoherence": ("ngi", "nli", "tnli", "max_bicoherence", "critical", "third_harmonic"),
    "horch": ("phase", "r_max", "kurtosis", "sine_share"),
    "ellipse": ("width_ratio", "phase_deg", "coherence", "band_share"),
    "kano": ("index", "travel_share", "still_share", "intervals", "dropped"),
    "hammerstein": ("improvement", "stats.explained", "stats.level", "stats.increments",
                    "stats.gain", "stats.spread", "stats.sigma", "stats.explained_linear",
                    "stats.explained_process", "stats.level_process"),
    "fast_cycle": ("kurtosis.0", "kurtosis.1", "corr"),
}
_GATES = ("cycle.period", "cycle.cycles", "cycle.regular", "cycle.from_pv",
          "cycle.op_regularity", "cycle.pv_regularity", "cycle.op_significance",
          "cycle.pv_significance", "process.integrating")
_SHAPE = ("shape.op_kurtosis", "shape.pv_kurtosis", "shape.op_jumps", "shape.pv_jumps")
NAMES: tuple[str, ...] = (
    *(f"{t}.{k}" for t in _TESTS for k in ("vote", "value")),
    *(f"{t}.{f}" for t, fs in _FIELDS.items() for f in fs), *_GATES, *_SHAPE)
"""The features, in vector order."""
TEST_OF: Mapping[str, str] = {n: n.split(".", 1)[0] if n.split(".", 1)[0] in _TESTS else
                              ("cycle" if n.startswith(("cycle", "process")) else "shape")
                              for n in NAMES}
"""The test (or "cycle", "shape") each feature belongs to, for the reason."""
_INDEX = {n: i for i, n in enumerate(NAMES)}


def _number(v: Any) -> float:
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, int | float) and math.isfinite(float(v)):
        return float(v)
    return math.nan


def _field(obj: Any, path: str) -> float:
    for part in path.split("."):
        if obj is None:
            return math.nan
        obj = obj[int(part)] if part.isdigit() and isinstance(obj, tuple) else \
            getattr(obj, part, None)
    return _number(obj)


def _kurtosis(x: FloatArray) -> float:
    z = x - x.mean()
    var = float(np.dot(z, z)) / z.size
    return float(np.dot(z * z, z * z)) / z.size / (var * var) if var > 0 else math.nan


def _shape(out: FloatArray, op: FloatArray, pv: FloatArray, period: float | None) -> None:
    if period is None or period < 2:
        return
    q = max(1, int(period // 20))
    m = (op.size // q) * q
    if m // q < 8:
        return
    for name, x in (("op", op), ("pv", pv)):
        y = x[:m].reshape(-1, q).mean(axis=1)
        out[_INDEX[f"shape.{name}_kurtosis"]] = _kurtosis(y)
        out[_INDEX[f"shape.{name}_jumps"]] = _kurtosis(y[1:] - y[:-1])


def features(evidence: tuple[Evidence, ...], results: Mapping[str, Any], cycle: Cycle, *,
             op: FloatArray, pv: FloatArray, integrating: bool) -> FloatArray:
    """The feature vector (:data:`NAMES` order) of a clean window ``op``, ``pv``."""
    out = np.full(len(NAMES), np.nan)
    for e in evidence:
        if e.test in _TESTS:
            out[_INDEX[f"{e.test}.vote"]] = float(e.vote)
            out[_INDEX[f"{e.test}.value"]] = _number(e.value)
    for test, fields in _FIELDS.items():
        r = results.get(test)
        for f in fields:
            out[_INDEX[f"{test}.{f}"]] = _field(r, f)
    p = cycle.period
    if p is not None and p > 0:
        out[_INDEX["cycle.period"]] = p
        out[_INDEX["cycle.cycles"]] = op.size / p
        out[_INDEX["cycle.from_pv"]] = float(cycle.source == "PV")
    out[_INDEX["cycle.regular"]] = float(cycle.regular)
    for name, sig in (("op", cycle.op), ("pv", cycle.pv)):
        out[_INDEX[f"cycle.{name}_regularity"]] = _number(min(sig.osc.regularity, 99.0))
        out[_INDEX[f"cycle.{name}_significance"]] = _number(sig.significance)
    out[_INDEX["process.integrating"]] = float(integrating)
    _shape(out, op, pv, p)
    return out
