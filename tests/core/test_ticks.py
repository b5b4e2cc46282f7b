"""core.ticks: the time rules of polling, each with a fake ``now``."""

from __future__ import annotations

import random

import numpy as np
import pytest

from gateway.core.ticks import (
    AUTH_RETRY_CAP_S,
    STALE_POLLS,
    Backoff,
    Link,
    ProcessClock,
    SetTracker,
    StaleTracker,
    TickGrid,
    stalled,
)


def test_process_clock() -> None:
    assert ProcessClock(1.0, start=100.0).now(130.0) == 130.0
    assert ProcessClock(40.0, start=100.0).now(101.5) == 160.0


def test_tick_grid_first_tick_and_missed_ticks() -> None:
    assert TickGrid(0.1).first_due(5.0) == 5.0
    grid = TickGrid(0.1, phase_ref=1.05)
    assert grid.first_due(5.0) == pytest.approx(5.05)
    assert grid.catch_up(10.0, 10.09) == (0, 10.0)  # late, but within the period
    missed, due = grid.catch_up(10.0, 10.35)  # ticks at 10.0, 10.1, 10.2 passed
    assert missed == 3 and due == pytest.approx(10.3)


def test_backoff_is_capped_jittered_and_resets() -> None:
    b = Backoff(base=0.5, factor=2.0, cap=8.0, rng=random.Random(1))
    ceilings = []
    delays = []
    for _ in range(12):
        ceilings.append(b.ceiling())
        delays.append(b.next_delay())
    assert ceilings[:5] == [0.5, 1.0, 2.0, 4.0, 8.0]
    assert max(ceilings) == 8.0
    assert all(0 <= d <= c for d, c in zip(delays, ceilings, strict=True))
    assert len(set(delays)) == len(delays)  # jittered, not lock-step
    b.reset()
    assert b.ceiling() == 0.5


def test_a_refused_login_backs_off_longer() -> None:
    b = Backoff(base=0.5, factor=2.0, cap=0.5, rng=random.Random(2))
    delays = [b.next_delay("auth") for _ in range(10)]
    # from the first refusal on, 30-60 s: retried, never sooner (nor later: issue 31, a
    # delay of 1e9 passed every test)
    assert all(AUTH_RETRY_CAP_S / 2 <= d <= AUTH_RETRY_CAP_S for d in delays), delays
    assert b.ceiling("connect") == 0.5
    assert b.ceiling("auth") == AUTH_RETRY_CAP_S  # at least a minute: no account lock-out
    assert Backoff(cap=300.0).cap_for("auth") == 300.0


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"base": 0}, "`base` must be > 0"),
    ({"factor": 0.5}, "`factor` must be >= 1"),
    ({"base": 2.0, "cap": 1.0}, "`cap` must be >= base"),
])
def test_backoff_validates(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Backoff(**kwargs)


def test_link_says_down_once_and_recovered_once() -> None:
    link = Link(Backoff(0.5, 2.0, 4.0, rng=random.Random(3)))
    assert link.up is None and link.may_connect(0.0)
    assert link.failed("connect", 10.0) is True  # down: log it
    first_retry = link.retry_at
    assert 10.0 <= first_retry <= 10.5
    assert not link.may_connect(first_retry - 1e-6) and link.may_connect(first_retry)
    assert link.failed("connect", first_retry) is False  # still down: no second line
    assert link.backoff.attempt == 2
    assert link.answered() is False  # it was down: log "recovered"
    assert link.backoff.attempt == 0 and link.up is True
    assert link.answered() is True  # already up: nothing to say
    assert Link(Backoff()).answered() is None  # the first answer ever


def test_stale_after_three_polls_without_a_fresh_sample() -> None:
    tracker = StaleTracker(2)
    # loop 0 fresh at polls 1-2, then not; loop 1 never
    fresh = [[True, False], [True, False], [False, False], [False, False], [False, False],
             [True, False]]
    got = [tracker.update(k + 1, np.array(f)).tolist() for k, f in enumerate(fresh)]
    assert STALE_POLLS == 3
    assert got == [[False, False], [False, False], [False, False], [False, True],
                   [True, True], [False, True]]


def test_set_tracker_says_what_came_and_went() -> None:
    t = SetTracker()
    assert t.update({"holding 0+4"}) == (["holding 0+4"], [])
    assert t.update({"holding 0+4"}) == ([], [])
    assert t.update({"input 8+2"}) == (["input 8+2"], ["holding 0+4"])
    assert t.update(()) == ([], ["input 8+2"])


def test_stalled() -> None:
    assert not stalled(100.0, None, 1.0, 2.0)  # no tick ran yet
    assert not stalled(100.0, 94.0, 1.0, 2.0)  # 6 s = period + 2 x guard + 1
    assert stalled(100.0, 93.9, 1.0, 2.0)
