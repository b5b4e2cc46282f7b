"""The hand-made plants simulated once per test process, and written as a historian would
export them."""

from __future__ import annotations

import datetime as dt
import functools
from pathlib import Path

from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import NAMED_PLANTS


@functools.cache
def plant_records() -> dict[str, PlantRecord]:
    """Every named plant, 2 h at 1 s after a 30 min warm-up (seed 3)."""
    recs = simulate_plants(list(NAMED_PLANTS.values()), duration=7200.0, seed=3)
    return {r.scenario.name: r for r in recs}


def write_wide_export(path: Path, rec: PlantRecord, *, names: dict[str, str] | None = None
                      ) -> Path:
    """``rec`` as a ';'-separated export with decimal commas and ISO time stamps, a column
    per signal named ``TAG.OP``/``TAG.PV`` (or as ``names`` maps them) and the indicators."""
    names = names or {}
    loops = list(rec.op)
    header = ["Timestamp"] + [names.get(f"{t}.{k}", f"{t}.{k}") for t in loops
                              for k in ("OP", "PV")] + list(rec.indicators)
    start = dt.datetime(2024, 3, 1, 6, 0, 0)
    with path.open("w", encoding="utf-8") as fh:
        fh.write(";".join(header) + "\n")
        for i in range(rec.op[loops[0]].size):
            cells = [(start + dt.timedelta(seconds=i * rec.ts)).isoformat(sep=" ")]
            cells += [f"{x:.4f}".replace(".", ",") for t in loops
                      for x in (rec.op[t][i], rec.pv[t][i])]
            cells += [f"{rec.indicators[k][i]:.4f}".replace(".", ",") for k in rec.indicators]
            fh.write(";".join(cells) + "\n")
    return path
