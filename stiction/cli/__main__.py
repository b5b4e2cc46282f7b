"""`python -m stiction.cli`: the `stiction` command."""

import sys

from . import main

sys.exit(main())
