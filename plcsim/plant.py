"""Plant scenarios in the simulated PLC: several interacting loops whose cycle has one
source (``plants:`` in the plc-sim config, docs/plc-sim.md).

A plant is one of :data:`stiction.scenarios.plants.NAMED_PLANTS` (e.g. ``sticky-feeds-two``:
a sticky flow valve whose cycle reaches a temperature and a level loop through the process).
Its loops are simulated together by :func:`stiction.scenarios.plant.simulate_plants` once,
at start, for ``duration_s`` process seconds after the model's warm-up, and replayed sample
by sample (from the start again after ``duration_s``: one jump per replay). Each loop takes
4 registers like any simulated loop (OP float32 % of span, PV float32), named
``prefix + loop``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from stiction.scenarios.plant import PlantLoop, PlantScenario, simulate_plants

__all__ = ["DEFAULT_DURATION_S", "PlantFeed", "SimPlant"]

DEFAULT_DURATION_S = 14400.0  # process seconds simulated at start (4 h), then replayed


@dataclasses.dataclass(frozen=True)
class SimPlant:
    """One plant of the simulated PLC: its loops' registers follow each other from
    ``address``."""

    scenario: PlantScenario
    prefix: str = ""
    address: int = 0
    window_s: float | None = None
    duration_s: float = DEFAULT_DURATION_S
    unit: str = ""  # the plant unit written for its loops (--write-gateway-config)

    @property
    def loops(self) -> tuple[PlantLoop, ...]:
        return self.scenario.loops

    def name(self, loop: PlantLoop) -> str:
        return f"{self.prefix}{loop.name}"


class PlantFeed:
    """The precomputed samples of ``plants``: :meth:`step` gives the next OP and PV of
    every plant loop (in plant then loop order)."""

    def __init__(self, plants: tuple[SimPlant, ...], ts: float, seed: int) -> None:
        self.k = 0
        self.op = np.zeros((0, 0))
        self.pv = np.zeros((0, 0))
        parts_op: list[NDArray[np.float64]] = []
        parts_pv: list[NDArray[np.float64]] = []
        steps = min((round(p.duration_s / ts) for p in plants), default=0)
        for i, p in enumerate(plants):
            (rec,) = simulate_plants([p.scenario], duration=steps * ts, ts=ts, seed=seed + i)
            parts_op += [rec.op[lp.name][:steps] for lp in p.loops]
            parts_pv += [rec.pv[lp.name][:steps] for lp in p.loops]
        if parts_op:
            self.op = np.stack(parts_op, axis=1)  # (steps, loops)
            self.pv = np.stack(parts_pv, axis=1)

    def step(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if self.op.shape[0] == 0:
            return np.zeros(0), np.zeros(0)
        k = self.k % self.op.shape[0]
        self.k += 1
        return self.op[k], self.pv[k]
