"""`stiction`: offline tools (simulate, signature, analyze, reproduce).

Exit status: 0 success, 2 bad arguments or unusable input (the message names the problem).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ._analyze import Details, analyze_details
from ._errors import ParameterError, StictionError
from ._switching import fitted_curve
from .reproduce import mean, qualifying_errors, reproduce
from .scenarios import SCENARIOS, scenario, simulate
from .signature import valve_signature
from .valves import HeValve

Handler = Callable[[argparse.Namespace], int]


class UsageError(Exception):
    """Bad command-line input: printed as ``stiction: error: ...`` with exit status 2."""


def _param_option(name: str) -> str:
    return "--" + name.replace("_", "-")


# ------------------------------------------------------------------------------ simulate
_SIM_PARAMS = ("fs", "fd", "k", "kc", "ti", "kp", "tau", "theta", "ts", "sp_step",
               "sp_step_time", "dist_amp", "dist_period", "load_sd", "load_tau")


def _add_simulate(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a named closed-loop scenario and write t, sp, op, pv, vp as CSV",
        description="Simulate a scenario. Scenarios: "
        + "; ".join(f"{k}: {s.description}" for k, s in SCENARIOS.items()),
    )
    p.add_argument("--scenario", required=True, help="scenario name (see above)")
    for name in _SIM_PARAMS:
        p.add_argument(_param_option(name), dest=name, type=float, default=None,
                       help=f"override the scenario's {name}")
    p.add_argument("--noise", type=float, default=0.0, help="PV noise SD, PV units (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--duration", type=float, default=None, help="seconds (default: scenario's)")
    p.add_argument("-o", "--output", required=True, type=Path, help="CSV file to write")
    p.set_defaults(handler=_cmd_simulate)


def _cmd_simulate(args: argparse.Namespace) -> int:
    overrides = {k: getattr(args, k) for k in _SIM_PARAMS if getattr(args, k) is not None}
    sc = scenario(args.scenario, **overrides)
    res = simulate(sc, duration=args.duration, noise=args.noise, seed=args.seed)
    data = np.column_stack([res.t, res.sp, res.op, res.pv, res.vp])
    try:
        with args.output.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t", "sp", "op", "pv", "vp"])
            w.writerows(np.round(data, 9).tolist())
    except OSError as exc:
        raise UsageError(f"cannot write {args.output}: {exc.strerror}") from exc
    sticky = f"fs {sc.fs:g}, fd {sc.fd:g}, K {sc.k:g}" if sc.sticky else "perfect valve"
    print(f"wrote {len(res.t)} samples ({res.t[-1] + sc.ts:g} s, Ts {sc.ts:g} s) of scenario "
          f"{sc.name} ({sticky}, noise SD {args.noise:g}) to {args.output}")
    return 0


# ----------------------------------------------------------------------------- signature
def _add_signature(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "signature",
        help="valve signature: physical vs semiphysical model (paper Figure 2)",
        description="Runs 0-12 psi at 0.02 psi/s (ZOH 1 s) through the Kayihan-Doyle physical "
        "valve (Table 1) and the normalised semiphysical model, and reports both.",
    )
    p.add_argument("--plot", type=Path, default=None, help="draw the signature to FILE.png")
    p.add_argument("--csv", type=Path, default=None, help="write u, x_physical, x_semi to CSV")
    p.set_defaults(handler=_cmd_signature)


def _cmd_signature(args: argparse.Namespace) -> int:
    sig = valve_signature()
    jumps_p = int(np.count_nonzero(np.abs(np.diff(sig.x_physical)) > 1e-6))
    jumps_s = int(np.count_nonzero(np.abs(np.diff(sig.x_semiphysical)) > 1e-6))
    print(f"semiphysical parameters from Table 1: fs {sig.fs:.4f}, fd {sig.fd:.4f}, "
          f"K {sig.k:.4f}")
    print(f"samples {len(sig.u)}; slips: physical {jumps_p}, semiphysical {jumps_s}")
    print(f"max |x_physical - x_semiphysical| = {sig.max_abs_difference:.2e} of travel")
    if args.csv is not None:
        np.savetxt(args.csv, np.column_stack([sig.u, sig.x_physical, sig.x_semiphysical]),
                   delimiter=",", header="u,x_physical,x_semiphysical", comments="")
        print(f"wrote {args.csv}")
    if args.plot is not None:
        plt = _pyplot()
        fig, ax = plt.subplots(figsize=(6, 5))
        ax.plot(sig.u, sig.x_physical, "b-", lw=2.5, label="physical (Kayihan-Doyle)")
        ax.plot(sig.u, sig.x_semiphysical, "r--", lw=1.2, label="semiphysical (He, K from eq 5)")
        ax.set_xlabel("valve input u / span")
        ax.set_ylabel("valve position x / travel")
        ax.set_title("Valve signature, 0-12 psi at 0.02 psi/s")
        ax.legend()
        fig.savefig(args.plot, dpi=100)
        print(f"wrote {args.plot}")
    return 0


def _pyplot() -> Any:
    try:  # optional dependency (the plot extra): imported only when a plot is asked for
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise UsageError("--plot needs matplotlib: pip install 'stiction-gateway[plot]'") from exc
    return plt


# ------------------------------------------------------------------------------- analyze
def _add_analyze(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "analyze",
        help="assess one CSV window of OP/PV: oscillation, stiction (SI), fd and fs",
        description="Reads OP and PV (and time) columns of a CSV file with a header row and "
        "prints the assessment. Empty or 'nan' cells are missing samples.",
    )
    p.add_argument("file", type=Path, help="CSV file with a header row")
    p.add_argument("--op", default="op", help="OP column (default op)")
    p.add_argument("--pv", default="pv", help="PV column (default pv)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--time", default=None, help="time column, s (default t)")
    g.add_argument("--ts", type=float, default=None, help="sample time, s (no time column)")
    p.add_argument("--kp", type=float, default=None, help="process gain, PV units per OP unit")
    p.add_argument("--delay", type=float, default=0.0, help="process dead time, s")
    p.add_argument("--process", choices=("self-regulating", "integrating"),
                   default="self-regulating")
    p.add_argument("--op-range", dest="op_range", nargs=2, type=float, metavar=("LO", "HI"),
                   default=None, help="OP at 0 %% and 100 %% valve span, to report sizes as "
                   "fractions of span (default: sizes in OP units; no OP range is assumed)")
    p.add_argument("--json", action="store_true", help="print the assessment as one JSON object")
    p.add_argument("--plot", type=Path, default=None, help="draw OP, PV and the fit to FILE.png")
    p.set_defaults(handler=_cmd_analyze)


def _read_columns(path: Path, names: Sequence[str]) -> dict[str, np.ndarray]:
    """Numeric columns ``names`` of a CSV file; empty and 'nan' cells become NaN."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:  # a byte-order mark is common
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read {path}: {exc}") from exc
    if not rows:
        raise UsageError(f"{path}: empty file (need a header row)")
    header = [h.strip() for h in rows[0]]
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name not in header:
            raise UsageError(f"{path}: no column {name!r} (columns: {', '.join(header)})")
        col = header.index(name)
        vals = np.empty(len(rows) - 1)
        for i, row in enumerate(rows[1:]):
            cell = row[col].strip() if col < len(row) else ""
            try:
                vals[i] = float(cell) if cell else np.nan
            except ValueError:
                raise UsageError(f"{path}: line {i + 2}, column {name!r}: not a number: "
                                 f"{cell!r}") from None
        out[name] = vals
    return out


def _cmd_analyze(args: argparse.Namespace) -> int:
    time_col = args.time if args.time is not None else ("t" if args.ts is None else None)
    names = [args.op, args.pv] + ([time_col] if time_col else [])
    try:
        cols = _read_columns(args.file, names)
    except UsageError as exc:
        if time_col == "t" and args.time is None and "no column 't'" in str(exc):
            raise UsageError(f"{exc}; give --time COL or --ts S") from None
        raise
    op, pv = cols[args.op], cols[args.pv]
    if op.size < 2:
        raise UsageError(f"{args.file}: {op.size} samples, need at least 2")
    notes: list[str] = []
    if time_col:
        ts, op, pv, notes = _on_grid(args.file, time_col, cols[time_col], op, pv)
    else:
        ts = args.ts
    op_range = None if args.op_range is None else tuple(args.op_range)
    d = analyze_details(op, pv, ts=ts, kp=args.kp, delay=args.delay, process=args.process,
                        op_range=op_range)
    a = dataclasses.replace(d.assessment, warnings=(*notes, *d.assessment.warnings))
    if args.json:
        print(json.dumps(a.to_dict()))
    else:
        print(f"verdict: {a.verdict}")
        print(f"reason:  {a.reason}")
        for key, val in a.to_dict().items():
            if key not in {"verdict", "reason", "warnings", "evidence"} and val is not None:
                print(f"  {key}: {val:.4g}" if isinstance(val, float) else f"  {key}: {val}")
        if a.evidence:
            print("  evidence (test, value, vote, what it saw):")
        for e in a.evidence:
            value = "-" if e.value is None else f"{e.value:.3g}"
            vote = {1: "stiction", -1: "not stiction"}.get(e.vote, "cannot tell")
            print(f"    {e.test:<14} {value:>8}  {vote:<12}  {e.note}")
        for w in a.warnings:
            print(f"  warning: {w}")
    if args.plot is not None:
        _plot_analysis(args.plot, d, ts, op_range)
        if not args.json:
            print(f"wrote {args.plot}")
    return 0


def _on_grid(path: Path, name: str, t: np.ndarray, op: np.ndarray, pv: np.ndarray
             ) -> tuple[float, np.ndarray, np.ndarray, list[str]]:
    """Put the rows on a regular grid of the median sample time: repeated time stamps keep
    their last row, missing rows become gaps (NaN), as a historian export needs."""
    if not np.all(np.isfinite(t)):
        line = int(np.flatnonzero(~np.isfinite(t))[0]) + 2
        raise UsageError(f"{path}: column {name!r} has a missing time at line {line}")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise UsageError(f"{path}: time goes backwards at line {int(back[0]) + 3} "
                         f"({t[back[0]]:g} -> {t[back[0] + 1]:g})")
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0:
        raise UsageError(f"{path}: column {name!r} holds one time only; give --ts S")
    ts = float(np.median(steps))
    k = np.round((t - t[0]) / ts).astype(np.int64)
    notes = []
    if k[-1] + 1 > 50 * t.size:
        raise UsageError(f"{path}: time stamps too irregular to put on a grid of {ts:g} s")
    grid_op = np.full(int(k[-1]) + 1, np.nan)
    grid_pv = grid_op.copy()
    grid_op[k], grid_pv[k] = op, pv  # a repeated index keeps the last row
    repeated = t.size - np.unique(k).size
    missing = grid_op.size - np.unique(k).size
    if repeated:
        notes.append(f"{repeated} rows repeat a time stamp (on a {ts:g} s grid): the last "
                     "of each kept")
    if missing:
        notes.append(f"{missing} samples missing from the {ts:g} s time grid: treated as gaps")
    return ts, grid_op, grid_pv, notes


def _plot_analysis(path: Path, d: Details, ts: float,
                   op_range: tuple[float, float] | None) -> None:
    plt = _pyplot()
    a = d.assessment
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    if d.op is None or d.pv is None:
        fig.suptitle(f"{a.verdict}: {a.reason}", fontsize=9)
        fig.savefig(path, dpi=90)
        return
    op, pv = d.op, d.pv
    t = np.arange(op.size) * ts
    ax1.plot(t, op, lw=1, label="OP")
    ax2.plot(t, pv, lw=1, label="PV")
    q = d.quantification
    if q is not None and q.switches is not None:
        sw = q.switches
        ax2.plot(t, fitted_curve(sw, pv.size), "r--", lw=1, label="fitted PV")
        ax2.plot(sw.onsets * ts, np.interp(sw.onsets, np.arange(pv.size), pv), "kv",
                 label="switching points")
        if q.jump_times is not None:
            ax1.plot(q.jump_times * ts, np.interp(q.jump_times, np.arange(op.size), op),
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
    ax2.set_xlabel("t, s")
    fig.suptitle(f"{a.verdict}: {a.reason}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


# ----------------------------------------------------------------------------- reproduce
def _add_reproduce(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "reproduce",
        help="run every case of He & Wang (2014) Tables 4-9 and compare with the paper",
        description="Simulates each case at its default duration, analyses it and prints the "
        "paper's fd, fs (error %%) beside ours, with SI and our verdict.",
    )
    p.add_argument("--noise", type=float, default=0.0, help="PV noise SD, PV units (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(handler=_cmd_reproduce)


def _fmt(v: float | None, err: float | None) -> str:
    return "     -        " if v is None or err is None else f"{v:.3f} ({err:5.1f}%)"


def _cmd_reproduce(args: argparse.Namespace) -> int:
    if not np.isfinite(args.noise) or args.noise < 0:
        raise ParameterError("noise", f"must be >= 0, was {args.noise!r}")
    rows = reproduce(noise=args.noise, seed=args.seed)
    print(f"He & Wang (2014) Tables 4-9, PV noise SD {args.noise:g}, seed {args.seed}")
    print(f"{'table':>5} {'case':<20} {'paper fd':>14} {'our fd':>14} {'paper fs':>14} "
          f"{'our fs':>14} {'paper SI':>8} {'our SI':>6}  verdict")
    for r in rows:
        p = r.paper
        si = "-" if r.assessment.stiction_index is None else f"{r.assessment.stiction_index:.2f}"
        psi = "" if p.si is None else f"{p.si:.2f} {p.verdict}"
        mj = " (multi-jump)" if r.multi_jump else ""
        if not r.clean_limit_cycle:
            mj += (f" [simulated valve: {r.true_jumps} jumps"
                   + (", often twice the same way]" if r.true_multi_jump else "]"))
        print(f"{p.table:>5} {p.case:<20} {_fmt(p.fd, p.fd_err):>14} {_fmt(r.fd, r.fd_err):>14} "
              f"{_fmt(p.fs, p.fs_err):>14} {_fmt(r.fs, r.fs_err):>14} {psi:>8} {si:>6}  "
              f"{r.assessment.verdict}{mj}")
    paper, ours = qualifying_errors(rows)
    worse = sum(o >= 5.0 for o in ours)
    left_out = sum(not r.clean_limit_cycle for r in rows)
    print(f"\nover the {len(paper)} fd/fs estimates where the paper's error is under 5 %: "
          f"mean abs error paper {mean(paper):.2f} %, ours {mean(ours):.2f} %; "
          f"ours >= 5 % on {worse}")
    if left_out:
        print(f"({left_out} rows left out of that: the simulated valve did not hold a "
              "single-jump limit cycle; see [...] above)")
    return 0


# ---------------------------------------------------------------------------------- main
_COMMANDS: list[Callable[[argparse._SubParsersAction[argparse.ArgumentParser]], None]] = [
    _add_simulate,
    _add_signature,
    _add_analyze,
    _add_reproduce,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="stiction", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler = args.handler
    try:
        return handler(args)
    except BrokenPipeError:  # `stiction analyze ... | head`: the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush is quiet
        return 1
    except ParameterError as exc:
        parser.exit(2, f"stiction: error: {_param_option(exc.name)}: {exc}\n")
    except (UsageError, StictionError) as exc:
        parser.exit(2, f"stiction: error: {exc}\n")
    return 0  # pragma: no cover


if __name__ == "__main__":
    sys.exit(main())
