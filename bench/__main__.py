"""Run every benchmark module (``make bench``). Long soak runs (``bench.soak``) are not
part of this: they have their own ``make soak``."""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

SKIP = {"__main__", "soak"}


def main() -> None:
    names = sorted(m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])
                   if m.name not in SKIP)
    for name in names:
        mod = importlib.import_module(f"bench.{name}")
        run = getattr(mod, "main", None)
        if callable(run):
            run()
            print()


if __name__ == "__main__":
    main()
