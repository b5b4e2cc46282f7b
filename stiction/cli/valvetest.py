"""`stiction valve-test`: a step test's recording (the loop in manual, OP stepped), read as
``analyze`` reads a historian export, and the valve's dead band, resolution, slip and
per-step response (:mod:`stiction.valvetest`)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from ..valvetest import StepResult, StepTestDetails, StepTestReport, step_test_details
from . import historian
from ._common import Subparsers, UsageError, pyplot

__all__ = ["add_valve_test"]


def add_valve_test(sub: Subparsers) -> None:
    p = sub.add_parser(
        "valve-test",
        help="a step test in manual: the valve's dead band, resolution, slip, response times",
        description="Reads a recording of a valve step test (the loop in manual, OP held "
        "and stepped up and down with reversals: ISA-75.25.01) as `analyze` reads a "
        "historian export, and prints per step whether the valve moved, how far, after how "
        "long (dead time, T63, T86) and its overshoot, and overall the dead band (OP "
        "travel after a reversal before the valve moves), the resolution (the smallest "
        "step it follows without a reversal) and the slip (how far it jumps when it "
        "breaks free). The response is read from PV, or from the valve position where a "
        "positioner reports it (--position, in OP's units).",
    )
    p.add_argument("file", type=Path, help="CSV file with a header row")
    p.add_argument("--op", default="op", help="OP column (default op; any case)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--pv", default=None, help="PV column (default pv; any case)")
    src.add_argument("--position", default=None,
                     help="valve position column (in OP's units): read the valve's own travel")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column: seconds or date-times "
                   "(default: t, time, timestamp, datetime, date time or date)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--process", choices=("auto", "self-regulating", "integrating"),
                   default="auto", help="PV's process: self-regulating (PV settles after a "
                   "step: flow, pressure, temperature), integrating (PV ramps: a level); "
                   "default auto, told from the data")
    p.add_argument("--kp", type=float, default=None, help="PV's process gain, PV units per "
                   "OP unit (per s for an integrating process): PV's changes are read as the "
                   "valve's travel through it (default: read from the steps that moved the "
                   "valve; not with --position)")
    p.add_argument("--op-range", dest="op_range", nargs=2, type=float, metavar=("LO", "HI"),
                   default=None, help="OP at 0 %% and 100 %% valve span, to report sizes in %% "
                   "of span (default: OP units)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.add_argument("--plot", type=Path, default=None, help="draw OP, the response and the "
                   "steps that moved the valve to FILE.png")
    p.set_defaults(handler=_cmd_valve_test)


def _read(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray, float, list[str]]:
    y = (args.position, "--position") if args.position is not None else (args.pv or "pv",
                                                                         "--pv")
    wanted = [(args.op, "--op"), y]
    table = historian.read_table(args.file, select=lambda header: historian.needed(
        header, args.file, wanted, args.time, args.ts))
    got = historian.read_signals(table, wanted, args.time, args.ts,
                                 None if args.op_range is None else tuple(args.op_range))
    return got.series[0], got.series[1], got.ts, got.notes


def _cmd_valve_test(args: argparse.Namespace) -> int:
    op, y, ts, notes = _read(args)
    op_range = None if args.op_range is None else tuple(args.op_range)
    if args.kp is not None and args.position is not None:
        raise UsageError("--kp is PV's process gain: the valve position is read in OP's "
                         "units without it (drop --kp, or read PV with --pv)")
    d = step_test_details(op, y, ts, source="position" if args.position else "pv",
                          process=args.process, op_range=op_range, kp=args.kp)
    r = d.report
    if args.json:
        out = r.to_dict()
        out["notes"] = [*notes, *out["notes"]]
        print(json.dumps(out))
    else:
        print(_text(r, [*notes, *r.notes]))
    if args.plot is not None:
        _plot(args.plot, d, op, y, ts)
        if not args.json:
            print(f"wrote {args.plot}")
    return 0


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "-" if x is None else format(x, spec)


def _band(name: str, value: float | None, bounds: tuple[float, float], unit: str) -> str:
    lo, hi = bounds
    if value is None:
        more = f" (more than {lo:.3g} {unit})" if lo > 0 else ""
        return f"{name:<11} not measured: no move bounded it{more}"
    if value == 0.0:
        return f"{name:<11} none seen (below the smallest step, {hi:.3g} {unit})"
    shown = f"{lo:.3g} .. {hi:.3g}" if math.isfinite(hi) else f"more than {lo:.3g}"
    return f"{name:<11} {value:.3g} {unit} ({shown})"


def _moved(s: StepResult) -> str:
    return "?" if s.moved is None else "yes" if s.moved else "no"


def _text(r: StepTestReport, notes: list[str]) -> str:
    src = "valve position" if r.source == "position" else f"PV ({r.process})"
    moved = sum(s.moved is True for s in r.steps)
    unread = sum(s.moved is None for s in r.steps)
    lines = [f"step test: {len(r.steps)} steps, {moved} moved the valve"
             + (f", {unread} cannot be read (?)" if unread else "")
             + f"; response read from {src}"
             + (f": dead time {r.dead_time_s:.3g} s, lag {r.lag_s:.3g} s"
                if r.dead_time_s is not None and r.lag_s is not None else "")
             + (f", gain {r.gain:.3g} per {r.unit.replace('OP units', 'OP unit')}"
                if r.gain is not None else ""),
             _band("dead band:", r.deadband, r.deadband_bounds, r.unit),
             _band("resolution:", r.resolution, r.resolution_bounds, r.unit),
             f"{'slip:':<11} " + (f"{r.slip:.3g} {r.unit}" if r.slip is not None else "-"),
             f"{'time s':>9} {'OP step':>8} {'moved':>5} {'travel':>8} {'gain':>6} "
             f"{'dead s':>7} {'T63 s':>7} {'T86 s':>7} {'overshoot':>9}"]
    for s in r.steps:
        over = "-" if s.overshoot is None else f"{100 * s.overshoot:.0f} %"
        lines.append(f"{s.time_s:9.0f} {s.op_step:8.3g} {_moved(s):>5} "
                     f"{_fmt(s.travel if s.moved else None):>8} {_fmt(s.gain, '.2f'):>6} "
                     f"{_fmt(s.dead_time_s, '.1f'):>7} {_fmt(s.t63_s, '.1f'):>7} "
                     f"{_fmt(s.t86_s, '.1f'):>7} {over:>9}")
    lines += [f"  note: {n}" for n in notes]
    return "\n".join(lines)


def _plot(path: Path, d: StepTestDetails, op: np.ndarray, y: np.ndarray, ts: float) -> None:
    plt = pyplot()
    r = d.report
    t = np.arange(op.size) * ts
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(14, 6.5), sharex=True)
    ax1.plot(t, op, lw=1, label="OP")
    ax2.plot(t, y, lw=0.8, label="position" if r.source == "position" else "PV")
    ax2.plot(t, d.moves.model, "r--", lw=0.8, label="fitted response")
    at = d.holds.step_at[1:] * ts
    ax1.plot(at[d.moved], d.holds.level[1:][d.moved], "kv", label="the valve moved")
    still = ~d.moved & ~d.reading.unread
    ax1.plot(at[still], d.holds.level[1:][still], "x", color="0.5", label="it did not")
    if d.reading.unread.any():
        ax1.plot(at[d.reading.unread], d.holds.level[1:][d.reading.unread], "o",
                 mfc="none", color="0.5", label="cannot be read")
    ax1.set_ylabel("OP")
    ax2.set_ylabel("position" if r.source == "position" else "PV")
    ax2.set_xlabel("s")
    db = "-" if r.deadband is None else f"{r.deadband:.3g}"
    res = "-" if r.resolution is None else f"{r.resolution:.3g}"
    fig.suptitle(f"dead band {db}, resolution {res}, slip {_fmt(r.slip)} ({r.unit})")
    for ax in (ax1, ax2):
        ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)
