"""``python -m lab {corpus | train [--write] | calibrate [--write]}`` (lab/commands.py)."""

import sys

from .commands import main

sys.exit(main(sys.argv[1:]))
