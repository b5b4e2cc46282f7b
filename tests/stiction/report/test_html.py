"""stiction.report: the page is self-contained, escapes what comes from files, lists the loops
in the order given and gives the suspects their sections."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser

import numpy as np

from stiction import Sizes
from stiction.report import CSP, Finding, Listed, Report, Trend, render
from stiction.report.svg import op_pv_svg, thin, trend_svg

HOSTILE = "<script>alert(1)</script><img src=x onerror=alert(2)>"


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def _trend() -> Trend:
    t = np.arange(0.0, 3600.0, 2.0)
    op = 50 + 5 * np.sign(np.sin(t / 120))
    return Trend(t, op, 50 + np.cumsum(op - 50) / 300, "2024-05-01 08:00")


def _page() -> tuple[str, Report]:
    loops = (
        Listed(f"FIC101{HOSTILE}", 1, 1.8, "stiction", 0.93, f"sticky {HOSTILE}",
               Sizes("% of span", 1.2, 1.5, 0.6, None, 3.1), "2024-05-01 08:00",
               "source of plant-wide group 1",
               (Finding("2024-05-03", "stiction", 1.1, 1.4, "J. Doe", f"packing {HOSTILE}",
                        "dead band 2.5 % of span"),),
               (("2024-04-30", "undetermined"), ("2024-05-01", "stiction")), _trend()),
        Listed("LIC7", 2, 1.0, "valve_not_responding", None, "stuck", trend=_trend()),
        Listed("TIC2", 3, 0.3, "no_stiction", 0.3),
        Listed("PIC9", 4, 0.0, "not_oscillating", 0.1),
    )
    report = Report(f"Unit {HOSTILE}", loops, (f"note {HOSTILE}",), sections=25)
    return render(report), report


def test_the_page_escapes_every_text_from_a_file_and_runs_nothing() -> None:
    page, _ = _page()
    parser = _Tags()
    parser.feed(page)
    tags = [t for t, _a in parser.tags]
    assert "script" not in tags
    assert all(not any(k.startswith("on") for k in a) for _t, a in parser.tags)
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    # the images are ours: data: SVG only, each naming the loop escaped inside
    images = [a for t, a in parser.tags if t == "img"]
    assert len(images) == 4  # trend and OP-PV plot of the two suspects
    for a in images:
        src = a["src"] or ""
        assert src.startswith("data:image/svg+xml;base64,")
        svg = base64.b64decode(src.split(",", 1)[1]).decode()
        assert "<script" not in svg and "<img" not in svg  # (the name is text in it)
        assert svg.startswith("<svg xmlns='http://www.w3.org/2000/svg'")


def test_the_page_loads_nothing_from_elsewhere() -> None:
    page, _ = _page()
    assert f'content="{CSP}"' in page and "default-src 'none'" in CSP
    assert not re.search(r"(src|href)=['\"](?!data:|#)", page)
    assert "http://" not in page.replace("http://www.w3.org/2000/svg", "")
    assert "https://" not in page and "@import" not in page and "url(" not in page


def test_the_list_is_in_the_order_given_and_the_suspects_have_sections() -> None:
    page, report = _page()
    listed = re.findall(r"<tr><td class='num'>(\d+)</td>", page)
    assert listed == ["1", "2", "3"]  # the calm loop is counted, not listed
    assert "and 1 loop(s) not judged on a cycle, not listed: not_oscillating 1." in page
    assert page.count("<section class='valve'") == 2
    assert "id='valve-1'" in page and "id='valve-2'" in page and "href='#valve-1'" in page
    assert "fd 1.2, fs 1.5, slip 0.6, band 3.1 (% of span)" in page
    assert "2024-05-03: dead band 2.5 % of span" in page
    assert "2024-04-30: undetermined; 2024-05-01: stiction" in page
    assert "The crew found it sticking on 2024-05-03: plan the repair." in page
    assert "Check now: OP moves and PV does not follow" in page
    few = render(Report("x", report.loops, sections=1))
    assert few.count("<section class='valve'") == 1
    assert "1 more suspect valve(s) without a section" in few


def test_the_plots_are_small_and_keep_every_slip() -> None:
    t = np.arange(100_000.0)
    y = np.zeros_like(t)
    y[54_321] = 9.0  # one slip among 100,000 samples
    xs, ys = thin(t, y, 500)
    assert xs.size <= 1000 and 9.0 in ys
    svg = trend_svg(t, y, y, op_label="OP", pv_label="PV", time_label="time", title="x")
    assert len(svg) < 60_000 and "<title>x</title>" in svg
    cycle = op_pv_svg(np.sin(t / 50), np.cos(t / 50), op_label="OP", pv_label="PV",
                      title="<&>")
    assert len(cycle) < 60_000 and "<title>&lt;&amp;&gt;</title>" in cycle
    empty = op_pv_svg([np.nan], [np.nan], op_label="OP", pv_label="PV", title="none")
    assert empty.endswith("</svg>")
