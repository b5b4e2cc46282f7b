"""The weighted vote's fit (lab/training/calibrate.py) as stiction/diagnosis/weights.py."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

import stiction

WEIGHTS_FILE = Path(stiction.__file__).resolve().parent / "diagnosis" / "weights.py"


def write_weights(beta: np.ndarray, tests: Sequence[str], path: Path = WEIGHTS_FILE) -> None:
    """``stiction/diagnosis/weights.py`` from the bias and weights ``beta`` of ``tests``."""
    k = len(tests)
    lines = [
        '"""Weights of the tests\' votes (written by ``python -m lab calibrate --write``;',
        "see lab/training/calibrate.py for the data and the fit). Do not edit by hand.\"\"\"",
        "",
        f"BIAS = {beta[0]:.4f}",
        "FOR = {  # added when the test votes +1 (says stiction)",
        *(f'    "{name}": {beta[1 + i]:.4f},' for i, name in enumerate(tests)),
        "}",
        "AGAINST = {  # subtracted when the test votes -1 (says not stiction)",
        *(f'    "{name}": {beta[1 + k + i]:.4f},' for i, name in enumerate(tests)),
        "}",
        "",
    ]
    path.write_text("\n".join(lines))
