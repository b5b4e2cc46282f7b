"""Small plots as SVG text from numpy arrays, for a report that needs no plotting library and
no network: the OP and PV trend of a window, and PV against OP (the loop's cycle, whose
shape tells a sticky valve: a parallelogram, or a rectangle for a level loop).

Each plot is a complete SVG document (``viewBox`` set, so it scales to the page and prints
sharp), drawn in dark strokes on white, its text escaped; the traces are thinned for size
(the trend keeps each pixel column's minimum and maximum, so no spike or slip is lost; the
OP-PV plot at most :data:`MAX_POINTS` points), so that a plot weighs a few tens of kB.
"""

from __future__ import annotations

import html
import itertools
import math

import numpy as np
from numpy.typing import ArrayLike

from .._validate import FloatArray

__all__ = ["MAX_POINTS", "op_pv_svg", "thin", "trend_svg"]

MAX_POINTS = 1200
FONT = "font-family='Helvetica,Arial,sans-serif' font-size='11'"
INK, OP_INK, PV_INK, GRID = "#222222", "#1f4e9c", "#a23b1c", "#dddddd"


def thin(x: FloatArray, y: FloatArray, columns: int) -> tuple[FloatArray, FloatArray]:
    """``(x, y)`` with at most two points (the minimum and the maximum of ``y``) per each
    of ``columns`` equal slices of the samples, in time order; NaN samples dropped."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size <= 2 * columns:
        return x, y
    edges = np.linspace(0, x.size, columns + 1).astype(int)
    keep: list[int] = []
    for lo, hi in itertools.pairwise(edges.tolist()):
        if hi <= lo:
            continue
        a, b = lo + int(np.argmin(y[lo:hi])), lo + int(np.argmax(y[lo:hi]))
        keep.extend(sorted({a, b}))
    idx = np.array(keep, dtype=int)
    return x[idx], y[idx]


def _range(v: FloatArray) -> tuple[float, float]:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    pad = (hi - lo) * 0.05 if hi > lo else max(abs(hi) * 0.05, 0.5)
    return lo - pad, hi + pad


def _ticks(lo: float, hi: float, n: int = 4) -> list[float]:
    """About ``n`` round values in [lo, hi]."""
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return [lo]
    raw = span / n
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step) + 1)]


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _path(xs: FloatArray, ys: FloatArray) -> str:
    return " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(xs.tolist(), ys.tolist(), strict=True))


def _panel(out: list[str], x: FloatArray, y: FloatArray, *,
           box: tuple[float, float, float, float], xr: tuple[float, float], ink: str,
           label: str) -> None:
    """One panel: frame, horizontal grid and labels, the trace."""
    left, top, w, h = box
    lo, hi = _range(y)
    for v in _ticks(lo, hi):
        py = top + h - (v - lo) / (hi - lo) * h
        out.append(f"<line x1='{left:.1f}' y1='{py:.1f}' x2='{left + w:.1f}' y2='{py:.1f}' "
                   f"stroke='{GRID}'/>")
        out.append(f"<text x='{left - 4:.1f}' y='{py + 4:.1f}' text-anchor='end' {FONT} "
                   f"fill='{INK}'>{_fmt(v)}</text>")
    out.append(f"<rect x='{left}' y='{top}' width='{w}' height='{h}' fill='none' "
               f"stroke='{INK}'/>")
    out.append(f"<text x='{left + 4}' y='{top + 13}' {FONT} fill='{ink}'>"
               f"{html.escape(label)}</text>")
    tx, ty = thin(x, y, int(w))
    if tx.size:
        xs = left + (tx - xr[0]) / (xr[1] - xr[0]) * w
        ys = top + h - (ty - lo) / (hi - lo) * h
        out.append(f"<polyline fill='none' stroke='{ink}' stroke-width='1.2' "
                   f"points='{_path(xs, ys)}'/>")


def trend_svg(t: ArrayLike, op: ArrayLike, pv: ArrayLike, *, op_label: str, pv_label: str,
              time_label: str, title: str, width: int = 640, height: int = 260) -> str:
    """OP over PV against time ``t`` (seconds from the window's start), one panel each."""
    ta = np.asarray(t, dtype=np.float64)
    opa, pva = np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64)
    finite = ta[np.isfinite(ta)]
    xr = (float(finite.min()), float(finite.max())) if finite.size > 1 else (0.0, 1.0)
    if xr[1] <= xr[0]:
        xr = (xr[0], xr[0] + 1.0)
    left, right, gap = 58.0, 12.0, 10.0
    w = width - left - right
    h = (height - 24.0 - 34.0 - gap) / 2.0
    out = [_head(width, height, title)]
    _panel(out, ta, opa, box=(left, 24.0, w, h), xr=xr, ink=OP_INK, label=op_label)
    _panel(out, ta, pva, box=(left, 24.0 + h + gap, w, h), xr=xr, ink=PV_INK, label=pv_label)
    base = 24.0 + 2 * h + gap
    scale, unit = _time_unit(xr[1] - xr[0])
    for v in _ticks(xr[0] / scale, xr[1] / scale, 6):
        px = left + (v * scale - xr[0]) / (xr[1] - xr[0]) * w
        out.append(f"<text x='{px:.1f}' y='{base + 14:.1f}' text-anchor='middle' {FONT} "
                   f"fill='{INK}'>{_fmt(v)}</text>")
    out.append(f"<text x='{left + w / 2:.1f}' y='{base + 29:.1f}' text-anchor='middle' "
               f"{FONT} fill='{INK}'>{html.escape(time_label)} ({unit})</text>")
    out.append(f"<text x='{left:.1f}' y='15' {FONT} font-weight='bold' fill='{INK}'>"
               f"{html.escape(title)}</text></svg>")
    return "".join(out)


def _time_unit(span_s: float) -> tuple[float, str]:
    if span_s >= 2 * 86400:
        return 86400.0, "days"
    if span_s >= 3 * 3600:
        return 3600.0, "h"
    if span_s >= 180:
        return 60.0, "min"
    return 1.0, "s"


def _head(width: int, height: int, title: str) -> str:
    return (f"<svg xmlns='http://www.w3.org/2000/svg' viewBox='0 0 {width} {height}' "
            f"width='{width}' height='{height}'><title>{html.escape(title)}</title>"
            f"<rect width='{width}' height='{height}' fill='white'/>")


def op_pv_svg(op: ArrayLike, pv: ArrayLike, *, op_label: str, pv_label: str, title: str,
              size: int = 260) -> str:
    """PV against OP, the samples joined in time order (at most :data:`MAX_POINTS`)."""
    opa, pva = np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64)
    ok = np.isfinite(opa) & np.isfinite(pva)
    opa, pva = opa[ok], pva[ok]
    if opa.size > MAX_POINTS:
        step = math.ceil(opa.size / MAX_POINTS)
        opa, pva = opa[::step], pva[::step]
    left, top, bottom, right = 58.0, 24.0, 34.0, 10.0
    w, h = size - left - right, size - top - bottom
    xr, yr = _range(opa), _range(pva)
    out = [_head(size, size, title)]
    for v in _ticks(*yr):
        py = top + h - (v - yr[0]) / (yr[1] - yr[0]) * h
        out.append(f"<line x1='{left}' y1='{py:.1f}' x2='{left + w}' y2='{py:.1f}' "
                   f"stroke='{GRID}'/><text x='{left - 4}' y='{py + 4:.1f}' "
                   f"text-anchor='end' {FONT} fill='{INK}'>{_fmt(v)}</text>")
    for v in _ticks(*xr):
        px = left + (v - xr[0]) / (xr[1] - xr[0]) * w
        out.append(f"<line x1='{px:.1f}' y1='{top}' x2='{px:.1f}' y2='{top + h}' "
                   f"stroke='{GRID}'/><text x='{px:.1f}' y='{top + h + 14}' "
                   f"text-anchor='middle' {FONT} fill='{INK}'>{_fmt(v)}</text>")
    out.append(f"<rect x='{left}' y='{top}' width='{w}' height='{h}' fill='none' "
               f"stroke='{INK}'/>")
    if opa.size:
        xs = left + (opa - xr[0]) / (xr[1] - xr[0]) * w
        ys = top + h - (pva - yr[0]) / (yr[1] - yr[0]) * h
        out.append(f"<polyline fill='none' stroke='{INK}' stroke-width='0.8' "
                   f"points='{_path(xs, ys)}'/>")
    out.append(f"<text x='{left + w / 2:.1f}' y='{size - 6}' text-anchor='middle' {FONT} "
               f"fill='{OP_INK}'>{html.escape(op_label)}</text>")
    out.append(f"<text x='12' y='{top + h / 2:.1f}' text-anchor='middle' {FONT} "
               f"fill='{PV_INK}' transform='rotate(-90 12 {top + h / 2:.1f})'>"
               f"{html.escape(pv_label)}</text>")
    out.append(f"<text x='{left:.1f}' y='15' {FONT} font-weight='bold' fill='{INK}'>"
               f"{html.escape(title)}</text></svg>")
    return "".join(out)
