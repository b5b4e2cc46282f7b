"""The development corpus's records: :class:`Window` (one loop, one window: issue 24) and
:class:`PlantRun` (many loops on one time base: issue 21), and the folds they fall in."""

from __future__ import annotations

import collections
import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

SOURCES = ("tep-mode1", "tep-mode2", "tep-mode3", "tep-mode4", "tep-mode5", "tep-mode6",
           "realistic", "plant", "tep-shared", "cases")
"""The fold keys: each TEP operating mode, the realistic simulations, the plant records,
the shared TEP runs and the single cases that once broke the analysis."""

CAUSE_CLASSES = ("stiction", "stiction-stuck", "stiction-masked", "normal", "disturbance",
                 "propagated", "tuning", "ramp-load", "non-stiction")
"""``stiction``: a sticky valve that stuck and slipped in the window. ``stiction-stuck`` and
``stiction-masked``: a sticky valve that hardly moved, or that OP noise dithered (TEP only,
see lab/labels/rules.py). ``normal``, ``disturbance``, ``propagated`` (another loop's
stick-slip cycle reaches this one), ``tuning`` and ``ramp-load`` (stiction.scenarios.realistic's
causes), ``non-stiction`` (a plant record labelled so, cause not documented)."""


@dataclasses.dataclass(frozen=True)
class Window:
    """One loop's OP and PV over one window, as the gateway would analyse it.

    ``source`` is the fold key (:data:`SOURCES`); ``run`` groups the windows of one run, tag
    or record set, so a fold never splits it; ``loop`` names the loop in its run;
    ``cause`` is fine-grained (``idv11``, ``idv1+idv12``, ``idv14+idv11``, ``normal``, a
    realistic cause, a plant loop type) and ``cause_class`` one of :data:`CAUSE_CLASSES`;
    ``sticky`` says the valve has stiction (whatever the window shows of it);
    ``stiction_size`` is its static friction fs in % of span (He's model; 0 for a good
    valve, nan when unknown); ``ts`` in seconds; ``process`` ``self-regulating`` or
    ``integrating``; ``view`` how it was sampled (``gateway``, ``historian``, ``study``,
    ``record``); ``t0`` its start in hours into the run (nan when unknown); ``meta`` the
    measured numbers behind the label."""

    source: str
    run: str
    loop: str
    cause: str
    cause_class: str
    sticky: bool
    op: np.ndarray
    pv: np.ndarray
    ts: float
    process: str
    note: str
    stiction_size: float
    view: str = "record"
    t0: float = float("nan")
    meta: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def key(self) -> str:
        """Unique within the corpus."""
        return f"{self.source}/{self.run}/{self.loop}/{self.view}@{self.t0:g}"


@dataclasses.dataclass(frozen=True)
class PlantRun:
    """Many loops of one run on one time base, for the plant-wide analysis (issue 21).

    ``loops`` maps a loop name to its (OP, PV); ``setpoints`` to its SP where known;
    ``indicators`` are the other measured signals (TEP: every XMEAS that is no loop's PV);
    ``labels`` the loop's cause class (as its windows'); ``sticky_loops`` the loops whose
    valve sticks (two for IDV 19, else at most one) and ``external`` True when a disturbance
    enters from outside the loops (any non-stiction IDV), False when not, None when
    unknown."""

    id: str
    source: str
    mode: str
    seed: int | None
    idvs: tuple[tuple[int, float], ...]
    bands: Mapping[str, float]
    ts: float
    loops: Mapping[str, tuple[np.ndarray, np.ndarray]]
    setpoints: Mapping[str, np.ndarray]
    indicators: Mapping[str, np.ndarray]
    labels: Mapping[str, str]
    sticky_loops: tuple[str, ...]
    external: bool | None
    note: str = ""
    meta: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def sticky_loop(self) -> str | None:
        """The sticky valve's loop when there is exactly one, else None."""
        return self.sticky_loops[0] if len(self.sticky_loops) == 1 else None


def folds(windows: Sequence[Window]) -> dict[str, list[int]]:
    """Leave-one-source-out folds: source -> indices of its windows. Raises ValueError if a
    run would fall in two folds (a run's windows must share their source)."""
    by_run: dict[str, str] = {}
    out: dict[str, list[int]] = collections.defaultdict(list)
    for i, w in enumerate(windows):
        if by_run.setdefault(w.run, w.source) != w.source:
            raise ValueError(f"run {w.run!r} is in sources {by_run[w.run]!r} and {w.source!r}")
        out[w.source].append(i)
    return dict(out)


def counts(windows: Iterable[Window]) -> dict[tuple[str, str], int]:
    """Windows per (source, cause_class)."""
    return dict(collections.Counter((w.source, w.cause_class) for w in windows))
