"""Which Tennessee Eastman runs the development corpus holds (no tep-studio here).

Per operating mode (1-6): three normal runs; every disturbance that is not a sticky valve
(IDV 1-13, 16-18, 20-28) alone at full magnitude and at a quarter or a half (alternating
over the modes, so each gets all three magnitudes across the corpus); five pairs of
disturbances (a different five per mode, fifteen pairs in all); the sticky valves at several
bands (IDV 14: reactor cooling water, XMV 10; IDV 15: condenser cooling water, XMV 11;
IDV 19: the group XMV 5, 7, 8, 9, of which XMV 7 and 8 are in loops), the reference band
of each with a second seed; and a sticky valve with a disturbance beside it (IDV 14 with
IDV 11, the random cooling-water temperature on the same loop, and with IDV 1; IDV 15 with
IDV 12 and with IDV 4). Every run has its own noise seed.
"""

from __future__ import annotations

import dataclasses

MODES = ("mode1", "mode2", "mode3", "mode4", "mode5", "mode6")
ALONE = tuple(i for i in range(1, 29) if i not in (14, 15, 19))
PARTIAL = (0.25, 0.5)  # besides 1.0: alternating over modes and disturbances
PAIRS = ((1, 12), (4, 11), (8, 13), (2, 20), (11, 12), (3, 21), (5, 27), (9, 16), (10, 17),
         (6, 22), (7, 23), (13, 18), (24, 25), (26, 28), (1, 8))
PAIRS_PER_MODE = 5
# sticky valve IDV -> bands (% of span); the model's own range is 0-2 %
BANDS = {14: (0.5, 1.0, 2.0, 4.0, 8.0), 15: (2.0, 4.0, 8.0, 12.0), 19: (1.0, 2.0, 4.0)}
REFERENCE_BAND = {14: 2.0, 15: 8.0, 19: 2.0}  # run twice, with two seeds
STICKY_WITH = ((14, 2.0, 11), (14, 2.0, 1), (15, 8.0, 12), (15, 8.0, 4))
STICKY_XMV = {14: (9,), 15: (10,), 19: (4, 6, 7, 8)}  # 0-based XMV indices


@dataclasses.dataclass(frozen=True)
class TepRun:
    """One closed-loop run: ``idvs`` are (IDV, magnitude 0-1) disturbances, ``sticky`` are
    (IDV 14/15/19, band in % of span) sticky valves."""

    mode: str
    seed: int
    idvs: tuple[tuple[int, float], ...] = ()
    sticky: tuple[tuple[int, float], ...] = ()

    @property
    def cause(self) -> str:
        """``normal``, ``idv11``, ``idv1+idv12``, ``idv14``, ``idv14+idv11``, ..."""
        parts = [f"idv{i}" for i, _ in self.sticky] + [f"idv{i}" for i, _ in self.idvs]
        return "+".join(parts) or "normal"

    @property
    def id(self) -> str:
        """Unique and readable: ``mode1-idv14@2%-s7``, ``mode2-idv3@0.25-s12``."""
        parts = [f"idv{i}@{b:g}%" for i, b in self.sticky]
        parts += [f"idv{i}@{m:g}" for i, m in self.idvs]
        return f"{self.mode}-{'+'.join(parts) or 'normal'}-s{self.seed}"

    @property
    def bands(self) -> dict[int, float]:
        """{0-based XMV index: band %} of the sticky valves."""
        return {x: band for idv, band in self.sticky for x in STICKY_XMV[idv]}

    @property
    def disturbed(self) -> bool:
        return bool(self.idvs)


def _mode_runs(mode: str) -> list[TepRun]:
    m = MODES.index(mode)
    specs: list[tuple[tuple[tuple[int, float], ...], tuple[tuple[int, float], ...]]] = []
    specs += [((), ())] * 3
    for idv in ALONE:
        specs.append((((idv, 1.0),), ()))
        specs.append((((idv, PARTIAL[(idv + m) % 2]),), ()))
    for k in range(PAIRS_PER_MODE):
        a, b = PAIRS[(m * PAIRS_PER_MODE + k) % len(PAIRS)]
        specs.append((((a, 1.0), (b, 1.0)), ()))
    for idv, bands in BANDS.items():
        specs += [((), ((idv, band),)) for band in bands]
        specs.append(((), ((idv, REFERENCE_BAND[idv]),)))
    specs += [(((other, 1.0),), ((idv, band),)) for idv, band, other in STICKY_WITH]
    return [TepRun(mode, 100 * (m + 1) + i + 1, idvs, sticky)
            for i, (idvs, sticky) in enumerate(specs)]


def plan(modes: tuple[str, ...] = MODES) -> list[TepRun]:
    """Every run of the corpus, normal runs of each mode first (the labels of a mode's
    other runs are measured against them)."""
    return [r for mode in modes for r in _mode_runs(mode)]
