"""Gaps in the plant view's signals: short ones bridged, long ones leave the signal out.

A missed poll or a historian's bad cell is one NaN in one loop's window; the per-loop
analysis bridges such gaps (``gateway.core.windows.analysis_segment``), and so does the
plant view: a run of missing samples of at most ``MAX_GAP`` samples, or ``MAX_GAP_SHARE`` of
the window if that is longer (a 30 s outage in an hour at 1 s), is filled by a straight
line between its neighbours, as long as no more than ``MAX_MISSING`` of the window is
missing in all. A signal with a longer gap, or with more missing, leaves the plant view
with its reason (the other signals stay); gaps at either end are filled with the nearest
value (a window not yet full, a poll that failed just now).
"""

from __future__ import annotations

import numpy as np

from .._validate import FloatArray

__all__ = ["MAX_GAP", "MAX_GAP_SHARE", "MAX_MISSING", "bridged"]

MAX_GAP = 3
MAX_GAP_SHARE = 0.02
MAX_MISSING = 0.1


def _runs(bad: np.ndarray) -> np.ndarray:
    """[begin, end) of each run of True in ``bad``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.view(np.int8), [0]))))
    return edges.reshape(-1, 2)


def bridged(x: FloatArray) -> tuple[FloatArray | None, str | None]:
    """``x`` with its gaps bridged, or (None, why) when a gap is too long (module doc);
    (x, None) unchanged when it has none."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return x, None
    n = x.size
    missing = int(np.count_nonzero(bad))
    if missing == n:
        return None, "no sample in its window"
    if missing > MAX_MISSING * n:
        return None, f"{missing} of its {n} samples missing (more than {MAX_MISSING:.0%})"
    longest = max(MAX_GAP, int(MAX_GAP_SHARE * n))
    runs = _runs(bad)
    inner = [(b, e) for b, e in runs.tolist() if b > 0 and e < n]
    worst = max((e - b for b, e in inner), default=0)
    if worst > longest:
        return None, (f"a gap of {worst} samples in its window (at most {longest} are "
                      "bridged)")
    idx = np.arange(n)
    return np.interp(idx, idx[~bad], x[~bad]), None
