"""Run every benchmark module in this package (each prints its own table).

`python -m bench` runs all; `python -m bench NAME ...` runs the named modules only.
Modules listed in SKIP (long soak runs) have their own make targets.
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


def main(argv: list[str]) -> int:
    here = Path(__file__).parent
    names = sorted(m.name for m in pkgutil.iter_modules([str(here)])
                   if not m.name.startswith("_") and m.name not in SKIP)
    chosen = argv or names
    unknown = [n for n in chosen if n not in names and n not in SKIP]
    if unknown:
        print(f"bench: unknown benchmark(s): {', '.join(unknown)} (known: {', '.join(names)})",
              file=sys.stderr)
        return 2
    for name in chosen:
        module = importlib.import_module(f"bench.{name}")
        module.main()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
