"""The report for the maintenance meeting: the list worst first and a section per suspect
valve, as one self-contained HTML page (:func:`render`; what it holds: :mod:`.page`; its
plots, SVG from numpy: :mod:`.svg`). Pure: dataclasses in, text out; the commands write it
(``stiction-gateway report``, ``stiction analyze --report``)."""

from __future__ import annotations

from .html import CSP, LIST_HEAD, render
from .page import SECTION_VERDICTS, Finding, Listed, Report, Trend, next_step
from .svg import op_pv_svg, trend_svg

__all__ = ["CSP", "LIST_HEAD", "SECTION_VERDICTS", "Finding", "Listed", "Report", "Trend",
           "next_step", "op_pv_svg", "render", "trend_svg"]
