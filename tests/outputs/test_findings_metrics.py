"""The findings' series (issue 30): per loop its latest finding (``none`` without one) and
that finding's day, rendered on the fast path exactly as the client library renders them;
per site the findings by the verdict of their day; promtool finds nothing to lint."""

from __future__ import annotations

import datetime as dt

import pytest
from deploy_support import require_tool, run
from prometheus_client import CollectorRegistry
from prometheus_client.exposition import choose_encoder

from gateway.config.findings import Finding, FindingsFile
from gateway.core.findings import FindingsBook, day_start
from gateway.core.store import ResultStore
from gateway.outputs.prometheus import GatewayMetrics, StoreCollector
from gateway.outputs.prometheus.findings import FindingsCollector
from gateway.runtime.findings import observe
from stiction import Assessment, Verdict

DAY = dt.date(2024, 3, 5)


def _registry() -> tuple[CollectorRegistry, StoreCollector]:
    store = ResultStore(["FIC101", "TIC301", 'odd "name"'])
    store.set_result(0, Assessment(Verdict.STICTION, "sticky"), t=day_start(DAY) - 3600.0,
                     window_fill=1.0, samples=100)
    book = observe(store, FindingsBook())
    store.set_result(0, Assessment(Verdict.STICTION, "sticky"), t=day_start(DAY) - 60.0,
                     window_fill=1.0, samples=100)
    book.apply(FindingsFile("f.csv", (Finding("FIC101", DAY, "stiction", 2.0, 3.0, line=2),
                                      Finding("TIC301", DAY, "ok", line=3)), ("bad row",)))
    registry = CollectorRegistry()
    GatewayMetrics(registry)
    collector = StoreCollector(store, book)
    registry.register(FindingsCollector(book))
    registry.register(collector)
    return registry, collector


def test_values() -> None:
    registry, _ = _registry()

    def v(name: str, **labels: str) -> float | None:
        return registry.get_sample_value(name, labels)

    assert v("stiction_loop_finding", loop="FIC101", finding="stiction") == 1.0
    assert v("stiction_loop_finding", loop="TIC301", finding="ok") == 1.0
    assert v("stiction_loop_finding", loop='odd "name"', finding="none") == 1.0
    assert v("stiction_loop_finding_timestamp_seconds", loop="FIC101") == day_start(DAY)
    assert v("stiction_loop_finding_timestamp_seconds", loop='odd "name"') is None
    assert v("stiction_findings_total", verdict="stiction", finding="stiction") == 1.0
    assert v("stiction_findings_total", verdict="unknown", finding="ok") == 1.0
    assert v("stiction_findings_problems") == 1.0


@pytest.mark.parametrize("accept", ["text/plain", "application/openmetrics-text"])
def test_the_fast_page_is_the_client_librarys(accept: str) -> None:
    registry, collector = _registry()
    encoder, ctype = choose_encoder(accept)
    fast = collector.page(registry, encoder, ctype.startswith("application/openmetrics"))
    assert fast == encoder(registry)
    assert b'stiction_loop_finding{finding="stiction",loop="FIC101"} 1.0' in fast


def test_promtool_finds_nothing() -> None:
    promtool = require_tool("promtool", "prometheus")
    registry, collector = _registry()
    encoder, _ = choose_encoder("text/plain")
    r = run([promtool, "check", "metrics"], input=collector.page(registry, encoder,
                                                                   False).decode())
    assert (r.returncode, r.stdout + r.stderr) == (0, "")


@pytest.fixture
def east_of_utc(monkeypatch: pytest.MonkeyPatch) -> object:
    """Local time an hour ahead of UTC, where year 1's midnight is before year 1 in UTC."""
    import time  # noqa: PLC0415

    monkeypatch.setenv("TZ", "Europe/Berlin")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


@pytest.mark.parametrize("cell", ["0001-01-01", "01.01.0001", "1969-12-31"])
def test_a_no_date_row_is_refused_and_never_fails_a_scrape(east_of_utc: object, tmp_path: object,
                                                           cell: str) -> None:
    """Issue 38 item 1: one row dated 0001-01-01 (a maintenance system's "no date") failed
    every /metrics scrape (500, "year 0 is out of range"). The file refuses the row; a view
    holding such a date anyway renders without its timestamp."""
    from pathlib import Path  # noqa: PLC0415

    from gateway.config.findings import read_findings  # noqa: PLC0415

    p = Path(str(tmp_path)) / "findings.csv"
    p.write_text(f"loop,date,finding\nFIC101,{cell},stiction\nTIC301,2024-03-05,ok\n")
    got = read_findings(p, ["FIC101", "TIC301"], today=DAY, shown_as="f.csv")
    assert [f.loop for f in got.findings] == ["TIC301"]
    assert got.problems == (f"f.csv: line 2: loop FIC101: column 'date': {cell!r} is before "
                            "1970 (the 'no date' of a maintenance system's export?): write "
                            "the day the crew found it",)
    registry, collector = _registry()
    assert collector.findings is not None
    collector.findings.apply(FindingsFile("f.csv", (Finding("FIC101", dt.date(1, 1, 1),
                                                            "stiction", line=2),)))
    encoder, _ = choose_encoder("text/plain")
    page = collector.page(registry, encoder, False)
    assert page == encoder(registry)
    assert b'stiction_loop_finding{finding="stiction",loop="FIC101"} 1.0' in page
    assert b"stiction_loop_finding_timestamp_seconds{" not in page
