"""``python -m bench.train [--write]``: the old name of ``python -m lab train [--write]``
(lab/commands.py)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from lab.commands import train


def main(argv: Sequence[str] = ()) -> None:
    train(argv)


if __name__ == "__main__":
    main(sys.argv[1:])
