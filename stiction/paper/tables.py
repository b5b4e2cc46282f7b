"""He & Wang (2014) Tables 4-9: every simulated case with the paper's own estimates.

One row per case: the scenario it simulates (see :mod:`stiction.scenarios`), what the method
is told (``kp``, ``delay``), the true fd/fs, and the paper's fd, fs, their errors (%), SI and
stiction verdict (Table 6 only). Errors are the paper's printed ones (rounded; they are
relative to the true value). Source: method notes section 5 and the paper's tables.
"""

from __future__ import annotations

import dataclasses
from typing import Any

__all__ = ["PAPER_ROWS", "PaperRow"]


@dataclasses.dataclass(frozen=True)
class PaperRow:
    table: int
    case: str  # the varied quantity, e.g. "tau=450"
    scenario: str
    overrides: tuple[tuple[str, Any], ...]  # scenario parameters
    kp: float  # gain the method is told
    delay: float  # dead time the method is told, s
    fd_true: float
    fs_true: float
    fd: float
    fd_err: float
    fs: float
    fs_err: float
    si: float | None = None
    verdict: str | None = None


def _rows() -> list[PaperRow]:
    rows = [
        PaperRow(4, "case 1", "table4-case1", (), 1.0, 0.0, 0.07, 0.08, 0.070, 0.13, 0.082, 2.26),
        PaperRow(4, "case 2", "table4-case2", (), 1.0, 0.0, 0.27, 0.30, 0.270, 0.00, 0.303, 1.06),
        PaperRow(5, "case 1", "table5-case1", (), 0.2, 1.0, 0.07, 0.08, 0.067, 3.71, 0.081, 0.98),
        PaperRow(5, "case 2", "table5-case2", (), 0.2, 1.0, 0.27, 0.30, 0.262, 2.96, 0.303, 1.06),
    ]
    t6 = [  # tau, fd, fd err, fs, fs err, SI, stiction?
        (90, 0.177, 1.7, 0.198, 1.0, 0.99, "yes"), (120, 0.177, 1.7, 0.195, 2.5, 1.00, "yes"),
        (150, 0.178, 1.1, 0.199, 0.5, 0.99, "yes"), (180, 0.178, 1.1, 0.197, 1.5, 0.95, "yes"),
        (210, 0.180, 0.0, 0.196, 2.0, 0.96, "yes"), (240, 0.184, 2.2, 0.198, 1.0, 0.98, "yes"),
        (270, 0.181, 0.6, 0.196, 2.0, 0.83, "yes"), (300, 0.186, 3.3, 0.198, 1.0, 0.89, "yes"),
        (330, 0.187, 3.9, 0.199, 0.5, 0.84, "yes"), (360, 0.189, 5.0, 0.199, 0.5, 0.79, "yes"),
        (390, 0.187, 3.9, 0.198, 1.0, 0.64, "yes"),
        (420, 0.196, 8.9, 0.206, 3.0, 0.51, "undetermined"),
        (450, 0.210, 16.7, 0.227, 13.5, 0.38, "no"), (480, 0.222, 23.3, 0.241, 20.5, 0.39, "no"),
    ]
    rows += [PaperRow(6, f"tau={tau}", "table6", (("tau", float(tau)),), 1.0, 6.0, 0.18, 0.20,
                      fd, fde, fs, fse, si, v) for tau, fd, fde, fs, fse, si, v in t6]
    t7 = [(0.177, 1.7, 0.197, 1.5), (0.178, 1.1, 0.199, 0.5), (0.180, 0.0, 0.201, 0.5),
          (0.178, 1.1, 0.199, 0.5), (0.179, 0.6, 0.200, 0.0), (0.178, 1.1, 0.199, 0.5),
          (0.179, 0.6, 0.200, 0.0)]
    rows += [PaperRow(7, f"theta={5 * (i + 1)}", "table7", (("theta", 5.0 * (i + 1)),), 1.0,
                      5.0 * (i + 1), 0.18, 0.20, *vals) for i, vals in enumerate(t7)]
    t8 = [(0.173, 3.8, 0.193, 3.3), (0.175, 3.0, 0.195, 2.3), (0.178, 1.2, 0.199, 0.7),
          (0.179, 0.7, 0.199, 0.3), (0.181, 0.6, 0.202, 0.9), (0.182, 1.1, 0.203, 1.7),
          (0.184, 2.0, 0.204, 2.2)]
    rows += [PaperRow(8, f"theta={5 * (i + 1)}, told 17", "table7", (("theta", 5.0 * (i + 1)),),
                      1.0, 17.0, 0.18, 0.20, *vals) for i, vals in enumerate(t8)]
    t9 = [(0.213, 6.7), (0.207, 3.7), (0.203, 1.6), (0.200, 0.0), (0.197, 1.3), (0.195, 2.3),
          (0.194, 3.1), (0.192, 3.8), (0.191, 4.3), (0.190, 4.8), (0.189, 5.3), (0.189, 5.6),
          (0.188, 6.0), (0.187, 6.3), (0.187, 6.5), (0.186, 6.8)]
    rows += [PaperRow(9, f"kp told {0.5 + 0.1 * i:.1f}", "table9", (), round(0.5 + 0.1 * i, 1),
                      6.0, 0.18, 0.20, 0.177, 1.4, fs, fse) for i, (fs, fse) in enumerate(t9)]
    return rows


PAPER_ROWS: tuple[PaperRow, ...] = tuple(_rows())
