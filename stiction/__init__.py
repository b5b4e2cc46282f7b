"""Valve stiction: models, closed-loop simulation, detection and quantification.

A numerical library with no IO: arrays and dataclasses in, dataclasses out.
Method: He, Pottmann & Qin (2007) for detection, He & Wang (2014) for quantification.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._assessment import Assessment, Evidence, Sizes, Verdict
from ._errors import ParameterError, StictionError
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

if TYPE_CHECKING:
    from .diagnosis.analyze import analyze


def __getattr__(name: str) -> Any:
    """``analyze`` on first use: it brings in scipy.signal and every detector (about 1 s),
    which the gateway's commands that only need the types (check-config, probe,
    result-map) should not pay at start."""
    if name == "analyze":
        from .diagnosis.analyze import analyze  # noqa: PLC0415

        return analyze
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
