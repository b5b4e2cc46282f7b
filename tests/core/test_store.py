"""core.store: the latest result, sample and stale flag per loop; snapshots."""

from __future__ import annotations

import numpy as np

from gateway.core.store import ResultStore
from stiction import Assessment, Verdict

STICKY = Assessment(Verdict.STICTION, "test", oscillating=True, period_s=200.0, fd=0.2)


def test_results_count_up_and_changes_are_announced() -> None:
    st = ResultStore(["A", "B"])
    heard: list[int] = []
    st.subscribe(heard.append)
    assert st.set_result(1, STICKY, t=1.0, window_fill=0.5, samples=10).seq == 1
    assert st.set_result(1, STICKY, t=2.0, window_fill=0.5, samples=10).seq == 2
    st.set_stale(np.array([0, 1]), np.array([True, False]))
    st.set_stale(np.array([0, 1]), np.array([True, False]))  # no change: nothing heard
    assert heard == [1, 1, 0]
    assert [st.verdict_name(i) for i in range(2)] == ["stale", "stiction"]
    st.restore_result(0, st.results[1])  # type: ignore[arg-type]
    assert st.results[0].seq == 2 and heard[-1] == 0  # type: ignore[union-attr]


def test_a_snapshot_does_not_change_with_the_store() -> None:
    st = ResultStore(["A"])
    st.latest_op[0] = 50.0
    snap = st.snapshot()
    st.latest_op[0] = 60.0
    st.set_result(0, STICKY, t=1.0, window_fill=1.0, samples=1)
    st.set_stale(np.array([0]), True)
    assert snap.latest_op[0] == 50.0 and snap.results == (None,)
    assert snap.verdict_name(0) == "none"
    assert st.snapshot().verdict_name(0) == "stale"
