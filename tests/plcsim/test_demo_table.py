"""Issue 32 item 7: the demo's table explains itself: a legend (`#`, `fill`, `SI`, the verdict
`none`), what each verdict on screen asks of the engineer with a link to the page that says
it at length, a "what" per plant loop; and the README promises no plant group a busy box
does not show."""

from __future__ import annotations

import io
import re
import types
from pathlib import Path

from gateway.core.store import ResultStore
from gateway.wire.results import VERDICT_CODES
from plcsim.demo import DEMO_LOOPS, VERDICT_ADVICE, plant_what, render_table
from stiction import Assessment, Verdict

REPO = Path(__file__).resolve().parents[2]


def _table(st: ResultStore) -> str:
    gw = types.SimpleNamespace(store=st, config=types.SimpleNamespace(
        gateway=types.SimpleNamespace(time_scale=40.0)))
    out = io.StringIO()
    render_table(gw, 0.0, out)  # type: ignore[arg-type]
    return out.getvalue()


def test_the_table_has_a_legend_and_advice_for_each_verdict_on_screen() -> None:
    names = [n for n, *_ in DEMO_LOOPS] + list(plant_what())
    st = ResultStore(names)
    st.set_result(0, Assessment(Verdict.STICTION, "sticks", fd=0.27, fs=0.30,
                                stiction_index=0.9), t=1.7e9, window_fill=1.0, samples=1800)
    st.set_result(1, Assessment(Verdict.UNDETERMINED, "unclear"), t=1.7e9, window_fill=1.0,
                  samples=1800)
    text = _table(st)
    flat = " ".join(text.split())
    for term in ("SI: stiction index", "fill: share of the loop's window", "#: analyses so far",
                 "fd, fs: dynamic and static friction, % of valve span"):
        assert term in flat, term
    assert "what to do (docs/modbus-map.md#verdict-codes):" in text
    for verdict in ("stiction", "undetermined", "none"):  # on screen: each with its advice
        assert re.search(rf"^  {verdict} +{re.escape(VERDICT_ADVICE[verdict][:30])}", text,
                         re.M), verdict
    assert "no_stiction" not in text  # not on screen: not explained
    assert max(len(line) for line in text.splitlines()[-12:]) <= 100


def test_every_verdict_has_advice_in_the_demo_and_in_the_register_map() -> None:
    assert set(VERDICT_ADVICE) == {str(v) for v in VERDICT_CODES}
    doc = (REPO / "docs" / "modbus-map.md").read_text()
    table = doc[doc.index("## Verdict codes"):doc.index("## Plant-wide groups")]
    rows = [r for r in table.splitlines() if re.match(r"\| \d+ \|", r)]
    assert [int(r.split("|")[1]) for r in rows] == sorted(VERDICT_CODES.values())
    names = []
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert len(cells) == 5 and cells[4], row  # code, verdict, name, meaning, what to do
        names.append(cells[2].strip("`"))
    assert names == sorted(VERDICT_CODES, key=VERDICT_CODES.__getitem__)


def test_each_plant_loop_says_what_it_is() -> None:
    what = plant_what()
    assert len(set(what.values())) == len(what) == 5
    assert what["U2.FIC101"] == "sticky flow valve (source)"
    assert what["U2.TIC201"] == "temperature, FIC101's cycle"
    assert what["U2.PIC401"] == "pressure, good valve"
    text = _table(ResultStore(list(what)))
    assert "plant sticky-feeds-two" not in text
    for name, w in what.items():
        assert re.search(rf"^{re.escape(name)} +{re.escape(w)} ", text, re.M)


def test_full_windows_without_a_group_are_not_called_filling() -> None:
    what = plant_what()
    st = ResultStore(list(what))
    for i in range(len(what)):
        st.set_result(i, Assessment(Verdict.NO_STICTION, "x"), t=1.7e9, window_fill=0.99,
                      samples=1200)
    assert "plant groups: none found this round" in _table(st)
    assert "needs full windows" in _table(ResultStore(list(what)))


def test_the_readme_does_not_promise_the_plant_group() -> None:
    readme = " ".join((REPO / "README.md").read_text().split())
    demo = readme[readme.index("## The demo"):readme.index("## The gateway")]
    assert "After about 30 s the plant's group appears" not in demo
    assert "depends on the windows each round sees" in demo
    assert "[verdict codes](docs/modbus-map.md#verdict-codes)" in demo
