"""Issue 35's and 37's findings about the plant-wide view (`stiction plant`), as cases: each
runs the command as a new user would, on a plant of the tree's own simulator."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from _case import case, run


def _plant(name: str, *, seed: int, duration: float = 7200.0, every: int = 1
           ) -> tuple[list[str], list[list[float]]]:
    """A named plant's export (header, rows): 1 s simulation, every ``every``-th row."""
    from stiction.scenarios.plant import simulate_plants  # noqa: PLC0415
    from stiction.scenarios.plants import NAMED_PLANTS  # noqa: PLC0415

    recs = simulate_plants(list(NAMED_PLANTS.values()), duration=duration, seed=seed)
    rec = next(r for r in recs if r.scenario.name == name)
    cols = {f"{t}.{k}": (rec.op if k == "OP" else rec.pv)[t] for t in rec.op
            for k in ("OP", "PV")}
    cols.update(rec.indicators)
    n = next(iter(cols.values())).size
    rows = [[float(i), *(float(v[i]) for v in cols.values())] for i in range(0, n, every)]
    return ["t", *cols], rows


def _stiction_plant(header: list[str], rows: list[list[float]], *args: str) -> dict[str, Any]:
    """``stiction plant FILE ARGS --json`` on the export, its JSON."""
    from stiction.cli import main  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plant.csv"
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            w.writerows(rows)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            main(["plant", str(path), *args, "--json"])
    data: dict[str, Any] = json.loads(out.getvalue())
    return data


def _fic101(data: dict[str, Any]) -> dict[str, Any] | None:
    return next((g for g in data["groups"] if any(x.endswith("FIC101") for x in g["loops"])),
                None)


@case("35.0", "sticky-feeds-two (the CLI test's plant, seed 3): FIC101's group holds "
              "FIC101, TIC201 and LIC301 only, on any machine (PIC401 joined at a "
              "coherence of 0.805 against 0.8)")
def plant_test_membership() -> tuple[str, bool]:
    header, rows = _plant("sticky-feeds-two", seed=3)
    g = _fic101(_stiction_plant(header, rows, "--integrating", "LIC301"))
    if g is None:
        return "no group", False
    return (f"{len(g['loops'])} loops: {', '.join(sorted(g['loops']))}",
            sorted(g["loops"]) == ["FIC101", "LIC301", "TIC201"])


@case("35.6", "an Ignition export ([default]U2/FIC101/OP): the loops are read as loops, "
              "FIC101 named the source, not 'enters from outside'")
def ignition_tag_paths() -> tuple[str, bool]:
    header, rows = _plant("sticky-feeds-two", seed=3, every=2)
    header = ["t", *(f"[default]U2/{h.replace('.', '/')}" for h in header[1:])]
    try:
        data = _stiction_plant(header, rows)
    except SystemExit:
        return "refused: no loop found", False
    g = _fic101(data)
    loops = len(data["loops"])
    if g is None:
        return f"{loops} loops, no group with FIC101", False
    said = f"{loops} loops; source {g['source']}, entry {g['entry']}"
    return said, loops == 5 and (g["source"] or "").endswith("FIC101") and g["entry"] is None


if __name__ == "__main__":
    run(sys.argv[1:])
