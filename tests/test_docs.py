"""The pages a plant engineer reads first (issue 32 item 6): docs/accuracy.md leads with the
held-out real figures, says what a verdict and its confidence are worth and when not to act,
marks in-sample figures, defines its jargon, keeps profiling on the performance page and
names where its data come from instead of paths a clone lacks; and the links between the
pages land on headings that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
ACCURACY = (DOCS / "accuracy.md").read_text()
FLAT = " ".join(ACCURACY.split())


def _sections(text: str) -> list[str]:
    return re.findall(r"^#+ (.+)$", text, re.M)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_the_held_out_real_figures_come_first() -> None:
    first = FLAT.index("## ", FLAT.index("## The bottom line") + 3)
    bottom = FLAT[:first]
    assert "found 16 of 35 sticky valve records" in bottom and "0 of 45" in bottom
    assert "held out" in bottom and "does not clear the valve" in bottom
    assert FLAT.index("16 of 35") < FLAT.index("in-sample") < FLAT.index("| tep-mode1 ")


def test_in_sample_figures_are_marked_so() -> None:
    for table in ("| sticky tags found", "| IDV 14 (sticky reactor valve)"):
        section = ACCURACY[:ACCURACY.index(table)].rsplit("\n### ", 1)[1]
        heading, _, intro = section.partition("\n")
        assert "in-sample" in heading and "**In-sample" in intro, table


def test_what_a_verdict_is_worth_and_when_not_to_act() -> None:
    worth = FLAT[FLAT.index("## What a verdict is worth"):FLAT.index("## When not to act")]
    for said in ("`undetermined` 0.55", "4 of the 5 such records were sticky valves",
                 "Do not send the valve to the workshop on it", "valve test",
                 "[verdict codes](modbus-map.md#verdict-codes)"):
        assert said in worth, said
    assert "at the corpus's prior" not in FLAT
    assert "## When not to act on the tool" in ACCURACY


@pytest.mark.parametrize("term", ["Saabas", "F0.5", "IDV", "NGI", "NLI", "held out",
                                  "in-sample", "precision", "stiction index", "Hammerstein"])
def test_jargon_is_defined_in_the_glossary(term: str) -> None:
    glossary = ACCURACY[ACCURACY.index("## Glossary"):]
    assert re.search(rf"^\* \*\*[^*]*{re.escape(term)}", glossary, re.M | re.I), term


def test_profiling_lives_on_the_performance_page() -> None:
    for word in ("FFT", "cProfile", "valgrind", "BLAS"):
        assert word not in ACCURACY, word
    perf = (DOCS / "performance.md").read_text()
    assert "## Against one FFT of the window" in perf and "[performance](performance.md)" \
        in ACCURACY


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_no_page_points_into_data_a_clone_lacks(page: Path) -> None:
    assert "../shared" not in page.read_text()


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_links_between_pages_land_on_headings(page: Path) -> None:
    text = page.read_text()
    for target, anchor in re.findall(r"\]\(((?:docs/)?[\w-]*\.md|)#([\w-]+)\)", text):
        linked = page if not target else (page.parent / target)
        assert linked.exists(), f"{page.name}: {target}"
        slugs = {_slug(h) for h in _sections(linked.read_text())}
        assert anchor in slugs, f"{page.name}: {target}#{anchor}"
