"""`stiction analyze --plot`: the window, the cycle and the OP-PV pattern in one figure, on
the export's own time axis (its date-times in their zone, or its seconds), so that the
stretch can be found on the historian's trend."""

from __future__ import annotations

import dataclasses
import datetime as dt
import importlib
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from ..diagnosis.analyze import Details
from ..models.valves import HeValve
from ..signal.switching import fitted_curve
from ._common import pyplot
from .grid import Stamps

VOTES = {1: "+", -1: "-", 0: "."}
VOTE_KEY = "test votes: + stiction, - not stiction, . cannot tell"


@dataclasses.dataclass(frozen=True)
class Clock:
    """When the analysed window starts: Unix seconds shown in ``zone`` for an export with
    date-times, else seconds as the export counts them (zone None)."""

    start: float
    zone: dt.tzinfo | None = None

    def axis(self, n: int, ts: float) -> tuple[Any, str]:
        """The x values of ``n`` samples ``ts`` apart and the axis label."""
        if self.zone is None:
            return self.start + np.arange(n) * ts, "t, s (the export's time)"
        first = dt.datetime.fromtimestamp(self.start, self.zone)
        x = [first + dt.timedelta(seconds=i * ts) for i in range(n)]
        return x, f"time ({first.tzname() or self.zone}, as the export's time stamps)"


def window_clock(t: Stamps | None, ts: float, op: np.ndarray, pv: np.ndarray) -> Clock:
    """The clock of the window ``analyze`` sees: it starts at the first sample where OP
    and PV are both finite (leading gaps are trimmed)."""
    good = np.flatnonzero(np.isfinite(op) & np.isfinite(pv))
    lead = float(good[0]) * ts if good.size else 0.0
    if t is None:
        return Clock(lead)
    return Clock(float(t.seconds[0]) + lead, t.zone)


def plot_analysis(path: Path, d: Details, ts: float, op_range: tuple[float, float] | None,
                  clock: Clock | None = None) -> Any:
    """Draw the figure to ``path``; returns it (closed)."""
    plt = pyplot()
    a = d.assessment
    title = textwrap.fill(f"{a.verdict}: {a.reason}", 150)
    fig = plt.figure(figsize=(14, 6.5))
    grid = fig.add_gridspec(2, 3)
    ax1 = fig.add_subplot(grid[0, :2])
    ax2 = fig.add_subplot(grid[1, :2], sharex=ax1)
    ax3 = fig.add_subplot(grid[:, 2])
    if d.op is None or d.pv is None:
        fig.suptitle(title, fontsize=8)
        fig.savefig(path, dpi=90)
        plt.close(fig)
        return fig
    op, pv = d.op, d.pv
    t, label = (clock or Clock(0.0)).axis(op.size, ts)

    def at(samples: np.ndarray) -> Any:
        """The x of fractional sample indices (switching points, jumps)."""
        if isinstance(t, np.ndarray):
            return t[0] + samples * ts
        return [t[0] + dt.timedelta(seconds=float(k) * ts) for k in samples]

    ax1.plot(t, op, lw=1, label="OP")
    ax2.plot(t, pv, lw=1, label="PV")
    q = d.quantification
    if q is not None and q.switches is not None:
        sw = q.switches
        ax2.plot(t, fitted_curve(sw, pv.size), "r--", lw=1, label="fitted PV")
        ax2.plot(at(sw.onsets), np.interp(sw.onsets, np.arange(pv.size), pv), "kv",
                 label="switching points")
        if q.jump_times is not None:
            ax1.plot(at(q.jump_times), np.interp(q.jump_times, np.arange(op.size), op),
                     "kv", label="valve jumps")
        if q.fs_op is not None and q.fd_op is not None and q.fs_op >= q.fd_op:
            lo, hi = (0.0, 100.0) if op_range is None else op_range
            span = hi - lo
            # scaled by 0.9 as the paper does (section 4.2) so that cycle-to-cycle
            # variability does not leave the rebuilt valve stuck
            valve = HeValve(0.9 * q.fs_op / span, 0.9 * q.fd_op / span, 1.99)
            u = (op - lo) / span
            st = valve.initial_state(u[0])
            vp = np.empty(u.size)
            for i, ui in enumerate(u):
                st = valve.step(st, ui)
                vp[i] = float(valve.position(st)[()])
            ax1.plot(t, lo + vp * span, lw=1, label="estimated VP")
    ax1.legend(loc="upper right", fontsize=8)
    ax2.legend(loc="upper right", fontsize=8)
    ax2.set_xlabel(label)
    if clock is not None and clock.zone is not None:
        dates = importlib.import_module("matplotlib.dates")  # there with pyplot (plot extra)
        ax2.xaxis.set_major_formatter(dates.DateFormatter("%Y-%m-%d\n%H:%M:%S",
                                                           tz=clock.zone))
    _plot_pattern(ax3, d, op, pv)
    fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return fig


def _plot_pattern(ax: Any, d: Details, op: np.ndarray, pv: np.ndarray) -> None:
    """The OP-PV pattern: the window's points and, where a cycle was found, the cycle with
    steps and drift removed (what the ellipse test fits), with the votes beside it."""
    ax.plot(op, pv, ".", ms=1.5, color="0.7", label="OP-PV")
    c = d.cycle
    if c is not None and c.cycling:
        x = c.op.x + float(np.mean(op))
        y = c.pv.x + float(np.mean(pv))
        ax.plot(x, y, "-", lw=0.5, color="tab:blue", label="the cycle, steps removed")
    ax.set_xlabel("OP")
    ax.set_ylabel("PV")
    ax.set_title("OP-PV pattern", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    text = "\n".join([VOTE_KEY, *(f"{VOTES.get(e.vote, '.')} {e.test}"
                                  for e in d.assessment.evidence)])
    if d.assessment.confidence is not None:
        text += f"\nconfidence {d.assessment.confidence:.2f}"
    ax.text(0.02, 0.02, text, transform=ax.transAxes, fontsize=7, family="monospace",
            va="bottom")
