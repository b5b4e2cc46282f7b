"""The hand-made plants simulated once per test process, and written as a historian would
export them."""

from __future__ import annotations

import datetime as dt
import functools
from pathlib import Path

import numpy as np

from gateway.config import LoopConfig, PointConfig
from gateway.core.points import Quality
from gateway.core.windows import LoopGroup, WindowBank, load_columns
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


def loop_group(loops: dict[str, tuple[np.ndarray, np.ndarray]], ts: float,
               processes: dict[str, str], device: str = "plc", *, first_row: int = 0,
               size: int | None = None, units: dict[str, str] | None = None,
               t0: float = 0.0) -> LoopGroup:
    """One device's loop group holding ``loops`` (name -> OP, PV) as full windows, every
    sample GOOD, the first at process time ``t0``; ``units``: each loop's plant unit."""
    names = list(loops)
    n = len(next(iter(loops.values()))[0])
    bank = WindowBank(names, size or n)
    q = np.full(n, Quality.GOOD, dtype=np.uint8)
    load_columns(bank, t0 + np.arange(n, dtype=np.float64) * ts,
                 {c: (op.astype(np.float32), pv.astype(np.float32), q)
                  for c, (op, pv) in enumerate(loops.values())})
    configs = tuple(LoopConfig(nm, device, PointConfig(None), PointConfig(None), 20 * k,
                               process=processes.get(nm, "self-regulating"),
                               unit=(units or {}).get(nm, ""))
                    for k, nm in enumerate(names))
    cols = np.arange(len(names), dtype=np.intp)
    return LoopGroup(device, bank, configs, cols, cols, cols + first_row, ts)
