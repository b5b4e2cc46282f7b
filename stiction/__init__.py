"""Valve stiction: models, closed-loop simulation, detection and quantification.

A numerical library with no IO: arrays and dataclasses in, dataclasses out.
Method: He, Pottmann & Qin (2007) for detection, He & Wang (2014) for quantification.
"""

from __future__ import annotations

from ._assessment import Assessment, Evidence, Sizes, Verdict
from ._errors import ParameterError, StictionError
from .diagnosis.analyze import analyze
from .models.valves import (
    ChoudhuryValve,
    HeValve,
    KanoValve,
    PhysicalParams,
    PhysicalValve,
    ValveModel,
    k_from_physical,
)

__all__ = [
    "Assessment",
    "ChoudhuryValve",
    "Evidence",
    "HeValve",
    "KanoValve",
    "ParameterError",
    "PhysicalParams",
    "PhysicalValve",
    "Sizes",
    "StictionError",
    "ValveModel",
    "Verdict",
    "analyze",
    "k_from_physical",
]

__version__ = "0.1.0"
