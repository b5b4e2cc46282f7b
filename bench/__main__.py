"""Run every benchmark module of this package's rooms (each prints its own table).

The rooms: ``accuracy`` (is the verdict right), ``speed`` (how fast and how big), ``attacks``
(the red team's), ``field`` (as a plant runs it); ``caselist`` and the lab's old command
names sit at the top. `python -m bench` runs all; `python -m bench NAME ...` runs the named
modules (``plantwide``) or whole rooms (``accuracy``). Modules listed in SKIP (long soak
runs) have their own make targets.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
from pathlib import Path

# own make targets (make soak, make corpus) or their own command (python -m lab train);
# corpus, train and calibrate here are the old names of lab's commands
SKIP = {"soak", "corpus", "corpus_baseline", "train"}
# as the gateway's analysis workers (gateway.runtime.scheduler): one BLAS thread each, set
# before numpy is first imported
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


ROOMS = ("accuracy", "speed", "attacks", "field")


def modules() -> dict[str, str]:
    """Every benchmark's name -> its module (``plantwide`` -> ``bench.accuracy.plantwide``),
    the rooms' in order, then the top's; SKIP's included (they run when named)."""
    here = Path(__file__).parent
    out: dict[str, str] = {}
    for prefix, folder in [*((f"bench.{r}.", here / r) for r in ROOMS), ("bench.", here)]:
        for m in sorted(pkgutil.iter_modules([str(folder)]), key=lambda m: m.name):
            if not m.name.startswith("_") and not m.ispkg:
                out.setdefault(m.name, prefix + m.name)
    return out


def main(argv: list[str]) -> int:
    known = modules()
    rooms = {r: [n for n, mod in known.items() if mod.startswith(f"bench.{r}.")
                 and n not in SKIP] for r in ROOMS}
    chosen: list[str] = []
    for name in argv or [n for n in known if n not in SKIP]:
        chosen += rooms.get(name, [name])
    unknown = [n for n in chosen if n not in known]
    if unknown:
        print(f"bench: unknown benchmark(s): {', '.join(unknown)} (known: rooms "
              f"{', '.join(ROOMS)}; {', '.join(n for n in known if n not in SKIP)})",
              file=sys.stderr)
        return 2
    for name in chosen:
        importlib.import_module(known[name]).main()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
