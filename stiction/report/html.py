"""One self-contained HTML page for the maintenance meeting (:func:`render`): the list worst
first, then a section per suspect valve, plain enough to print.

Self-contained: no script, no font, no style sheet and no image from elsewhere; the plots
are SVG documents embedded as ``data:`` images (:mod:`.svg`), and a Content-Security-Policy
forbids every other source (``default-src 'none'``), so the page opens offline and a text
that slipped through unescaped could still load or run nothing. Every text that comes from
a file (tag names, reasons, the crew's notes) is escaped (:func:`html.escape`).
"""

from __future__ import annotations

import base64
import collections
import html
from collections.abc import Iterable

from .page import Listed, Report, next_step
from .svg import op_pv_svg, trend_svg

__all__ = ["CSP", "LISTED", "LIST_HEAD", "VERDICT_COLOURS", "render"]

CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"
VERDICT_COLOURS = {
    "stiction": "#f2b8b0", "valve_not_responding": "#f7d08a", "undetermined": "#fbeaa0",
    "no_stiction": "#cfe6c4", "propagated": "#c9daf0",
}
"""The list's verdict cells, tinted (light enough to print in grey); others are white."""
_STYLE = """
body { font-family: Helvetica, Arial, sans-serif; font-size: 13px; color: #111; margin: 16px;
  max-width: 1100px; }
h1 { font-size: 20px; margin: 0 0 4px 0; } h2 { font-size: 16px; margin: 18px 0 6px 0; }
p.note { margin: 2px 0; color: #333; }
table { border-collapse: collapse; } th, td { border: 1px solid #999; padding: 2px 6px;
  text-align: left; vertical-align: top; } th { background: #eee; }
td.num { text-align: right; white-space: nowrap; }
table.list { width: 100%; } table.facts th { width: 12em; }
section.valve { border-top: 2px solid #444; margin-top: 18px; }
.plots img { margin: 4px 8px 4px 0; border: 1px solid #ccc; max-width: 100%; }
@media print { section.valve { break-before: page; } .plots img { break-inside: avoid; }
  body { margin: 0; } }
""" + "".join(f"td.v-{v} {{ background: {c}; }}\n" for v, c in VERDICT_COLOURS.items())


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _num(x: float | None, fmt: str = ".2f") -> str:
    return "-" if x is None else format(x, fmt)


def _verdict_cell(verdict: str) -> str:
    cls = f"v-{verdict}" if verdict in VERDICT_COLOURS else "v-other"
    return f"<td class='{cls}'>{_e(verdict)}</td>"


def _image(svg: str, alt: str) -> str:
    data = base64.b64encode(svg.encode("utf-8")).decode("ascii")
    return f"<img alt='{_e(alt)}' src='data:image/svg+xml;base64,{data}'>"


def _sizes(loop: Listed) -> tuple[str, str, str, str]:
    s = loop.sizes
    if s is None:
        return "-", "-", "-", ""
    return (_num(s.fd, ".3g"), _num(s.fs, ".3g"), _num(s.jump, ".3g"), s.unit)


def _list_rows(loops: Iterable[Listed], sections: set[int | None]) -> list[str]:
    rows = []
    for lp in loops:
        fd, fs, slip, unit = _sizes(lp)
        name = (f"<a href='#valve-{lp.rank}'>{_e(lp.name)}</a>"
                if lp.rank in sections else _e(lp.name))
        if lp.source:
            name += f"<br><small>{_e(lp.source)}</small>"
        last = lp.findings[-1] if lp.findings else None
        found = "-" if last is None else f"{_e(last.finding)} ({_e(last.date)})"
        rows.append(
            f"<tr><td class='num'>{_e(lp.rank or '-')}</td><td>{name}</td>"
            f"{_verdict_cell(lp.verdict)}<td class='num'>{_num(lp.confidence)}</td>"
            f"<td class='num'>{_num(lp.score)}</td><td class='num'>{fd}</td>"
            f"<td class='num'>{fs}</td><td class='num'>{slip}</td><td>{_e(unit)}</td>"
            f"<td>{_e(lp.since or '-')}</td><td>{_e(lp.role or '-')}</td><td>{found}</td>"
            "</tr>")
    return rows


LISTED = frozenset({*VERDICT_COLOURS})
"""The verdicts the list shows a row for (judged on a cycle, a valve not responding, a
follower); the others are counted under it."""
LIST_HEAD = ("#", "loop", "verdict", "confidence", "suspicion", "fd", "fs", "slip", "unit",
             "since", "plant-wide role", "last finding")


def _list(report: Report, sections: set[int | None]) -> str:
    shown = [lp for lp in report.loops if lp.verdict in LISTED]
    rest = [lp for lp in report.loops if lp.verdict not in LISTED]
    head = "".join(f"<th>{h}</th>" for h in LIST_HEAD)
    out = ["<section id='list'><h2>Valves to check, worst first</h2>",
           f"<table class='list'><thead><tr>{head}</tr></thead><tbody>",
           *_list_rows(shown, sections), "</tbody></table>"]
    if rest:
        counts = collections.Counter(lp.verdict for lp in rest)
        said = ", ".join(f"{_e(v)} {n}" for v, n in sorted(counts.items()))
        out.append(f"<p class='note'>and {len(rest)} loop(s) not judged on a cycle, not "
                   f"listed: {said}.</p>")  # (error: a file not analysed)
    out.append("</section>")
    return "".join(out)


def _facts(lp: Listed) -> str:
    fd, fs, slip, unit = _sizes(lp)
    rows = [("verdict", f"{lp.verdict}, confidence of stiction {_num(lp.confidence)} "
                        f"({lp.calibration} calibration)"),
            *([("samples from", lp.source)] if lp.source else []),
            ("since", lp.since or "-"), ("place in the list", f"{lp.rank or '-'}, "
                                                              f"suspicion {_num(lp.score)}")]
    if lp.sizes is not None:
        band = "" if lp.sizes.band is None else f", band {lp.sizes.band:.3g}"
        rows.append(("size", f"fd {fd}, fs {fs}, slip {slip}{band} ({unit})"))
    else:
        rows.append(("size", "not sized"))
    rows.append(("plant-wide role", lp.role or "in no group"))
    if lp.travel:
        rows.append(("valve travel", lp.travel))
    tests = [f"{f.date}: {f.step_test}" for f in lp.findings if f.step_test]
    if tests:
        rows.append(("step test", "; ".join(tests)))
    return ("<table class='facts'>" + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>"
                                             for k, v in rows) + "</table>")


def _plots(lp: Listed) -> str:
    tr = lp.trend
    if tr is None or tr.t.size < 2:
        return "<p class='note'>No window of samples to show.</p>"
    start = f" from {tr.start}" if tr.start else ""
    trend = trend_svg(tr.t, tr.op, tr.pv, op_label=f"OP ({tr.op_unit})",
                      pv_label=f"PV ({tr.pv_unit})", time_label=f"time{start}",
                      title=f"{lp.name}: OP and PV")
    cycle = op_pv_svg(tr.op, tr.pv, op_label=f"OP ({tr.op_unit})",
                      pv_label=f"PV ({tr.pv_unit})", title=f"{lp.name}: PV against OP")
    return ("<div class='plots'>" + _image(trend, f"{lp.name}: OP and PV over the window")
            + _image(cycle, f"{lp.name}: PV against OP") + "</div>")


def _section(lp: Listed) -> str:
    out = [f"<section class='valve' id='valve-{lp.rank}'><h2>{_e(lp.rank)}. {_e(lp.name)}: "
           f"{_e(lp.verdict)}</h2>", _facts(lp)]
    if lp.reason:
        out.append(f"<p><b>Reason.</b> {_e(lp.reason)}</p>")
    if lp.history:
        steps = "; ".join(f"{_e(d)}: {_e(v)}" for d, v in lp.history)
        out.append(f"<p><b>Verdict history.</b> {steps}</p>")
    out.append(_plots(lp))
    if lp.findings:
        rows = "".join(
            f"<tr><td>{_e(f.date)}</td><td>{_e(f.finding)}</td><td class='num'>"
            f"{_num(f.fd, '.3g')}</td><td class='num'>{_num(f.fs, '.3g')}</td>"
            f"<td>{_e(f.by)}</td><td>{_e(f.note)}</td></tr>" for f in lp.findings)
        out.append("<p><b>The crew's findings.</b></p><table><tr><th>date</th><th>finding"
                   "</th><th>fd %</th><th>fs %</th><th>by</th><th>note</th></tr>"
                   f"{rows}</table>")
    else:
        out.append("<p><b>The crew's findings.</b> None recorded.</p>")
    out.append(f"<p><b>What to do next.</b> {_e(next_step(lp))}</p></section>")
    return "".join(out)


def render(report: Report) -> str:
    """The report as one HTML document (module doc)."""
    suspects = [lp for lp in report.loops if lp.suspect and lp.rank is not None]
    chosen = suspects[: report.sections]
    places = {lp.rank for lp in chosen}
    notes = "".join(f"<p class='note'>{_e(n)}</p>" for n in report.notes)
    more = len(suspects) - len(chosen)
    tail = (f"<p class='note'>{more} more suspect valve(s) without a section: the list names "
            "them.</p>" if more > 0 else "")
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<meta http-equiv='Content-Security-Policy' content=\"{CSP}\">"
            f"<title>{_e(report.title)}</title><style>{_STYLE}</style></head><body>"
            f"<header><h1>{_e(report.title)}</h1>{notes}</header>{_list(report, places)}"
            + "".join(_section(lp) for lp in chosen) + tail
            + (f"<p class='note'>{_e(report.generated)}</p>" if report.generated else "")
            + "</body></html>\n")
