"""The maintenance meeting's page in a real browser (issue 39's acceptance): headless Chromium
(Debian's `chromium`, installed by .ci/run; under CI=true a missing browser fails, never
skips) opens a page `stiction analyze --manifest ... --report` wrote for a unit of simulated
loops, one of them named like an attack: the page renders, every image loads, it asks for
nothing but itself and its data: images, no console message, exception or CSP violation
(escaping and the page's policy both hold), and a screenshot of the first screen shows the
list, its worst loop's verdict cell in the stiction tint and ink in its name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cdp import Browser
from deploy_support import require_tool

from stiction.cli import main
from stiction.report.html import VERDICT_COLOURS
from stiction.scenarios import scenario, simulate

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]
HOSTILE = "<img src=x onerror=console.error('xss')><script>console.error('xss')</script>"
LOOPS = [("FIC101", "table4-case2", 1), (HOSTILE, "table4-case1", 2),
         ("TIC301", "aggressive-tuning", 1), ("PIC401", "healthy", 1),
         ("LIC201", "disturbance", 1)]


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("report")
    rows = ["file,loop"]
    for k, (name, kind, seed) in enumerate(LOOPS):
        r = simulate(scenario(kind), noise=0.02, seed=seed, duration=3000.0)
        np.savetxt(d / f"L{k}.csv", np.column_stack([r.t, r.op, r.pv]), delimiter=",",
                   header="t,op,pv", comments="", fmt="%.9g")
        rows.append(f"L{k}.csv,\"{name}\"")
    (d / "loops.csv").write_text("\n".join(rows) + "\n")
    out = d / "report.html"
    assert main(["analyze", "--manifest", str(d / "loops.csv"), "--op-range", "0", "100",
                 "--report", str(out)]) == 0
    return out


def _rgb(colour: str) -> tuple[int, int, int]:
    return int(colour[1:3], 16), int(colour[3:5], 16), int(colour[5:7], 16)


def test_the_report_renders_in_headless_chromium(page: Path, tmp_path: Path) -> None:
    exe = require_tool("chromium", "chromium")
    with Browser(exe, tmp_path) as b:
        b.open(page.as_uri())
        images = b.evaluate("Array.from(document.images).map(i => [i.complete, "
                            "i.naturalWidth, i.naturalHeight, i.src.slice(0, 25)])")
        rows = b.evaluate("Array.from(document.querySelectorAll('table.list tbody tr'))"
                          ".map(r => Array.from(r.cells).map(c => c.textContent))")
        first = b.evaluate("(() => { const c = document.querySelector('table.list tbody tr')"
                           ".cells; const v = c[2].getBoundingClientRect(); const n = c[1]"
                           ".getBoundingClientRect(); return [v.left, v.top, v.right, "
                           "v.bottom, n.left, n.top, n.right, n.bottom]; })()")
        scripts = b.evaluate("document.scripts.length")
        width, height, shot = b.screenshot()
        b.call("Runtime.evaluate", expression="1")  # collect the events still on the way
    # the page: every plot an image that loaded, the suspects' two each
    assert len(images) == 4
    assert all(ok and w > 100 and h > 100 and src == "data:image/svg+xml;base64"
               for ok, w, h, src in images), images
    # the list: the two sticky loops first (the hostile name as text), the calm one counted
    assert [r[0] for r in rows] == ["1", "2", "3", "4"]
    assert {rows[0][2], rows[1][2]} == {"stiction"}
    assert any(r[1].startswith(HOSTILE) and r[1].endswith("L1.csv") for r in rows[:2])
    assert scripts == 0
    # nothing asked of the network, nothing said on the console (a CSP violation would be)
    asked = [e["params"]["request"]["url"] for e in b.events
             if e["method"] == "Network.requestWillBeSent"]
    assert asked and all(u.startswith(("file:", "data:")) for u in asked), asked
    said = [e for e in b.events if e["method"] in ("Runtime.consoleAPICalled",
                                                   "Runtime.exceptionThrown")
            or (e["method"] == "Log.entryAdded"
                and e["params"]["entry"]["level"] in ("error", "warning"))]
    assert said == []
    # the first screen shows the list: the worst loop's verdict cell in the stiction tint,
    # and ink (text) in its loop cell
    assert (width, height) == (1280, 900)
    vl, vt, vr, vb, nl, nt, nr, nb = (round(v) for v in first)
    assert 0 < vt < vb < height and 0 < vl < vr < width, first
    tint = _rgb(VERDICT_COLOURS["stiction"])
    cell = [shot[y][3 * x:3 * x + 3] for y in range(vt + 2, vb - 2) for x in range(vl + 2, vr - 2)]
    share = sum(tuple(p) == tint for p in cell) / len(cell)
    assert share > 0.5, share  # the tint, under the verdict's text
    ink = [shot[y][3 * x:3 * x + 3] for y in range(nt + 2, nb - 2) for x in range(nl + 2, nr - 2)]
    assert sum(max(p) < 100 for p in ink) > 20  # the name's letters
