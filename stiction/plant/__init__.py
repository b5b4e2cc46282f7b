"""The plant-wide view: which loops share an oscillation, which loop is its source, and
which only follow it (:func:`analyze_plant`; method in :mod:`.groups` and :mod:`.source`)."""

from __future__ import annotations

from .analysis import Group, LoopRole, Member, PlantAssessment, analyze_plant
from .source import MemberEvidence

__all__ = ["Group", "LoopRole", "Member", "MemberEvidence", "PlantAssessment",
           "analyze_plant"]
