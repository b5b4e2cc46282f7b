"""The scale bench machinery at a tiny size (2 PLCs, 20 loops, 2 s), so it cannot rot.

No timing is asserted: only that the children start, poll, report and are cleaned up, and
that the counts the bench derives are consistent."""

from __future__ import annotations

import pytest

from bench.speed._scale import min_requests, run_scale


def test_min_requests_covers_used_registers_only() -> None:
    assert min_requests([(0, 2), (2, 2)]) == 1
    assert min_requests([(a, 2) for a in range(0, 500, 2)]) == 4  # 500 registers
    assert min_requests([(0, 2), (1000, 2)]) == 2  # a gap is not read
    assert min_requests([(0, 2), (100, 2)], max_registers=100) == 2
    assert min_requests([]) == 0


@pytest.mark.e2e
def test_scale_bench_runs_at_tiny_size() -> None:
    r = run_scale(20, plcs=2, duration=2.0, warmup=0.5)
    assert (r.loops, r.plcs) == (20, 2)
    assert r.min_requests == r.planned_requests == 2  # 40 contiguous registers per PLC
    assert r.requests_per_cycle == pytest.approx(2.0, rel=0.2)  # a poll cut at exit
    assert 0 < r.stored <= r.expected
    assert r.expected % 20 == 0
    assert r.jitter_p99_ms >= r.jitter_p50_ms
    assert r.cpu_percent > 0
    assert r.rss_mib > 0
    assert r.bytes_per_sample > 8
