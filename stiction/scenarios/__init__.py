"""Data to test the diagnosis against: the paper's and other named closed loops
(:mod:`.named`) and realistic loops with known causes (:mod:`.realistic`, drawn by
:mod:`.draws`). Built on :mod:`stiction.models`; never imports the detectors or the
diagnosis."""

from __future__ import annotations

from .named import SCENARIOS, Scenario, SimResult, scenario, simulate

__all__ = ["SCENARIOS", "Scenario", "SimResult", "scenario", "simulate"]
