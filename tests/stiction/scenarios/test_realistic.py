"""The realistic loop generator (stiction.scenarios.realistic): what each record promises."""

from __future__ import annotations

import numpy as np
import pytest

from stiction import ParameterError
from stiction.scenarios.realistic import CAUSES, MIN_CYCLES, MIN_SLIPS, realistic_loops


@pytest.fixture(scope="module")
def sticky() -> list:  # type: ignore[type-arg]
    return realistic_loops("stiction", 2, seed=5)


def test_records_are_reproducible() -> None:
    a = realistic_loops("noise", 1, seed=9)
    b = realistic_loops("noise", 1, seed=9)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.op, y.op)
        np.testing.assert_array_equal(x.pv, y.pv)
        assert x.description == y.description
    c = realistic_loops("noise", 1, seed=10)
    assert not np.array_equal(a[0].pv[:100], c[0].pv[:100])


def test_sticky_records_hold_their_cycles(sticky: list) -> None:  # type: ignore[type-arg]
    assert len(sticky) == 2
    for r in sticky:
        assert r.sticky
        assert r.fs > r.fd > 0
        assert 300 <= r.op.size <= 10_000
        assert r.op.size == r.pv.size == r.vp.size
        moves = np.flatnonzero(np.abs(np.diff(r.vp)) > 1e-9)
        starts = moves[np.concatenate(([True], np.diff(moves) > 1))]
        assert starts.size >= MIN_SLIPS // 2  # slips, counted on the historian's samples
        period = 2.0 * float(np.median(np.diff(starts)))  # two slips a cycle
        assert r.op.size >= 0.5 * MIN_CYCLES * period  # holds its cycles (sampling blurs)


def test_op_in_its_own_units_and_range(sticky: list) -> None:  # type: ignore[type-arg]
    recs = sticky + realistic_loops("noise", 3, seed=1)
    for r in recs:
        lo, hi = r.op_range
        assert lo < hi
        span = hi - lo
        # OP stays inside its span (the controller clamps at 0 and 100 %)
        assert r.op.min() >= lo - 1e-6 * span
        assert r.op.max() <= hi + 1e-6 * span
        assert np.all(np.isfinite(r.op))
        assert np.all(np.isfinite(r.pv))
    units = {r.description.split("OP in ")[1].split(";")[0] for r in recs}
    assert len(units) > 1  # not every record in % of span


@pytest.mark.parametrize("cause", [c for c in CAUSES if c != "stiction"])  # that: above
def test_every_cause_draws(cause: str) -> None:
    (r,) = realistic_loops(cause, 1, seed=2)
    assert r.cause == cause
    assert r.sticky == (cause == "stiction")
    assert r.ts in (1.0, 2.0, 5.0, 10.0, 30.0, 60.0)


def test_bad_arguments_name_themselves() -> None:
    with pytest.raises(ParameterError, match="cause"):
        realistic_loops("stuck", 1)
    with pytest.raises(ParameterError, match="count"):
        realistic_loops("noise", -1)
    with pytest.raises(ParameterError, match="count"):
        realistic_loops("noise", 1.5)  # type: ignore[arg-type]
    assert realistic_loops("noise", 0) == []
