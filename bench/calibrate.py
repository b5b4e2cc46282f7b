"""``python -m bench calibrate`` and ``python -m bench.calibrate [--write]``: the old names of
``python -m lab calibrate [--write]`` (lab/commands.py)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from lab.commands import calibrate


def main(argv: Sequence[str] = ()) -> None:
    calibrate(argv)


if __name__ == "__main__":
    main(sys.argv[1:])
