"""Assessments and a result store the output tests share (Prometheus, the result registers,
the result server): one sticky loop sized with kp, one oscillating loop without stiction,
one never assessed."""

from __future__ import annotations

import numpy as np

from gateway.core.store import ResultStore
from stiction import Assessment, Verdict

STICKY = Assessment(Verdict.STICTION, "test", oscillating=True, period_s=228.0,
                    stiction_index=0.93, fd=0.27, fs=0.30, jump=0.03, fd_op=27.0, fs_op=30.0,
                    cycles_used=6, confidence=0.91)
NO_KP = Assessment(Verdict.NO_STICTION, "test", oscillating=True, period_s=600.0,
                   stiction_index=0.01)


def sample_store(*, latest: bool = True) -> ResultStore:
    """FIC101 assessed twice (STICKY), FIC401 once (NO_KP), TIC301 never; with ``latest``
    the latest OP and PV of the first two (TIC301's NaN)."""
    st = ResultStore(["FIC101", "FIC401", "TIC301"])
    st.set_result(0, STICKY, t=1_700_000_000.5, window_fill=1.0, samples=1800)
    st.set_result(0, STICKY, t=1_700_000_300.0, window_fill=0.5, samples=1800)
    st.set_result(1, NO_KP, t=1_700_000_300.0, window_fill=0.25, samples=900)
    if latest:
        st.latest_op[:] = [51.5, 49.0, np.nan]
        st.latest_pv[:] = [50.2, 47.0, np.nan]
    return st
