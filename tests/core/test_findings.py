"""The verdict a loop had on a date, and the findings beside it (gateway.core.findings), on
literal histories with a UTC calendar."""

from __future__ import annotations

import datetime as dt

from gateway.config.findings import Finding, FindingsFile
from gateway.core.findings import UNKNOWN, FindingsBook, VerdictHistory

DAY = 86400.0
T0 = dt.datetime(2024, 3, 1, tzinfo=dt.UTC).timestamp()  # a midnight


def utc_day(t: float) -> int:
    return dt.datetime.fromtimestamp(t, dt.UTC).date().toordinal()


def d(day: int) -> dt.date:
    return dt.date(2024, 3, 1 + day)


def test_the_verdict_of_a_day_is_the_one_in_force_when_it_began() -> None:
    h = VerdictHistory(utc_day)
    h.record("A", T0 + 10 * 3600, "no_stiction")  # day 0: the first verdict of the day
    h.record("A", T0 + 20 * 3600, "stiction")
    h.record("A", T0 + DAY + 9 * 3600, "stiction")  # day 1 began with stiction in force
    h.record("A", T0 + DAY + 15 * 3600, "no_stiction")  # repaired that day
    h.record("A", T0 + 3 * DAY + 1, "warming_up")  # no call: not recorded
    assert h.verdict_on("A", dt.date(2024, 2, 29)) == UNKNOWN  # before its history
    assert h.verdict_on("A", d(0)) == "no_stiction"
    assert h.verdict_on("A", d(1)) == "stiction"  # the call that sent the crew
    assert h.verdict_on("A", d(2)) == "no_stiction"
    assert h.verdict_on("A", d(30)) == "no_stiction"  # the latest call stands
    assert h.verdict_on("B", d(1)) == UNKNOWN


def test_a_flickering_verdict_costs_one_entry_a_day() -> None:
    h = VerdictHistory(utc_day)
    for k in range(3 * 288):  # every 5 minutes for 3 days
        h.record("A", T0 + 300.0 * k, "stiction" if k % 2 else "undetermined")
    assert len(h.loops["A"].days) <= 3
    h.record("A", T0 + 1.0, "no_stiction")  # older than the latest: ignored
    assert h.loops["A"].verdict == "stiction"


def test_history_round_trips_and_a_newer_one_wins() -> None:
    h = VerdictHistory(utc_day)
    h.record("A", T0 + 3600, "stiction")
    h.record("A", T0 + DAY + 3600, "no_stiction")
    data = h.to_data()
    # day 2 began as day 1 did (stiction): no second entry
    assert data == {"A": {"days": ["2024-03-01"], "verdicts": ["stiction"],
                          "t": T0 + DAY + 3600, "verdict": "no_stiction"}}
    fresh = VerdictHistory(utc_day)
    fresh.record("A", T0 + 5 * DAY, "undetermined")  # recorded since start: newer
    fresh.record("B", T0 + 60, "bad_data")
    fresh.load({**data, "B": {"days": ["2024-02-01"], "verdicts": ["stiction"],
                              "t": T0 - DAY, "verdict": "stiction"}})
    assert fresh.loops["A"].verdict == "undetermined"
    assert fresh.loops["B"].verdict == "bad_data"
    other = VerdictHistory(utc_day)
    other.load(data)
    assert other.verdict_on("A", d(1)) == "stiction"
    assert other.verdict_on("A", d(2)) == "no_stiction"


def test_the_book_counts_each_finding_against_its_days_verdict() -> None:
    book = FindingsBook(VerdictHistory(utc_day))
    book.record("A", T0 + 3600, "stiction")
    book.record("B", T0 + 3600, "no_stiction")
    rows = (Finding("A", d(1), "stiction", line=2), Finding("B", d(1), "ok", line=3),
            Finding("A", d(0), "deadband", line=4), Finding("C", d(1), "other", line=5))
    assert book.apply(FindingsFile("f.csv", rows, ("f.csv: line 6: ...",)))
    v = book.view
    assert dict(v.counts) == {("stiction", "stiction"): 1, ("no_stiction", "ok"): 1,
                              ("stiction", "deadband"): 1, (UNKNOWN, "other"): 1}
    assert v.latest["A"].line == 2 and v.problems == 1  # the later date, not the later line
    # a file that cannot be read keeps the findings; a None (no findings key) clears them
    assert not book.apply(FindingsFile("f.csv", (), ("f.csv: cannot read",), readable=False))
    assert len(book.findings) == 4 and book.view.problems == 1
    book.apply(None)
    assert book.findings == () and dict(book.view.counts) == {}


class _Counting(VerdictHistory):
    """A history that counts how often a finding is compared with it."""

    calls = 0

    def verdict_on(self, loop: str, date: dt.date) -> str:
        self.calls += 1
        return super().verdict_on(loop, date)


def _from_scratch(book: FindingsBook) -> dict[tuple[str, str], int]:
    counts: dict[tuple[str, str], int] = {}
    for f in book.findings:
        key = (VerdictHistory.verdict_on(book.history, f.loop, f.date), f.finding)
        counts[key] = counts.get(key, 0) + 1
    return counts


def test_a_rounds_cost_is_the_findings_of_the_loops_that_changed() -> None:
    """Issue 38 item 2: the view was rebuilt whole each time one loop's first verdict (or a
    new day) changed the history: 2,000 loops with 6,000 findings held the event loop 10 s.
    Now each change compares only its loop's findings: the first verdicts of 300 loops with
    900 findings compare each finding about once, not 300 times (counted, not timed)."""
    loops = [f"L{k}" for k in range(300)]
    kinds = ("stiction", "ok", "deadband")
    rows = tuple(Finding(lp, d(k % 3), kinds[k % 3], line=2 + 3 * i + k)
                 for i, lp in enumerate(loops) for k in range(3))
    history = _Counting(utc_day)
    book = FindingsBook(history)
    book.apply(FindingsFile("f.csv", rows))
    assert history.calls == len(rows)
    history.calls = 0
    for day in range(4):  # the first verdicts, then three new days, every loop each round
        for r in range(3):
            for k, lp in enumerate(loops):
                verdict = ("stiction", "no_stiction")[(k + day + (r == 2)) % 2]
                book.record(lp, T0 + day * DAY + 3600 * (r + 1), verdict)
        assert dict(book.view.counts) == _from_scratch(book), day
    # each round that changed a loop compares its 3 findings again: at most 3 per record
    assert history.calls <= 3 * 4 * 3 * len(loops)
    assert history.calls >= len(rows)  # every finding was compared again at least once
    first_day = _from_scratch(book)
    assert sum(first_day.values()) == len(rows)
    assert first_day[("stiction", "stiction")] + first_day[("no_stiction", "stiction")] == 300
