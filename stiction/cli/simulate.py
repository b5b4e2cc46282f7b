"""`stiction simulate` and `stiction signature`: a named closed loop, a valve signature."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from ..models.signature import valve_signature
from ..scenarios.named import SCENARIOS, Scenario, SimResult, scenario, simulate
from ..scenarios.plant import simulate_plants
from ..scenarios.plants import NAMED_PLANTS
from ..scenarios.steptest import simulate_step_test
from ..valvetest.sequence import step_test_levels
from ._common import Subparsers, UsageError, param_option, pyplot
from .historian import write_export

# ------------------------------------------------------------------------------ simulate
_SIM_PARAMS = ("fs", "fd", "k", "kc", "ti", "kp", "tau", "theta", "ts", "sp_step",
               "sp_step_time", "dist_amp", "dist_period", "load_sd", "load_tau")


def add_simulate(sub: Subparsers) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a named closed-loop scenario and write t, sp, op, pv, vp as CSV "
             "(or a plant of many loops: --plant)",
        description="Simulate a scenario. Scenarios: "
        + "; ".join(f"{k}: {s.description}" for k, s in SCENARIOS.items())
        + ". Plants (--plant, a wide export for `stiction plant`: t, then TAG.OP and TAG.PV "
        "of every loop and the indicators): "
        + "; ".join(f"{k}: {s.description}" for k, s in NAMED_PLANTS.items()),
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--scenario", help="scenario name (see above)")
    which.add_argument("--plant", choices=sorted(NAMED_PLANTS), metavar="NAME",
                       help="a plant of interacting loops (see above); --duration (default "
                       "7200 s), --ts (the export's sample time, whole seconds, default 1) "
                       "and --seed apply")
    for name in _SIM_PARAMS:
        p.add_argument(param_option(name), dest=name, type=float, default=None,
                       help=f"override the scenario's {name}")
    p.add_argument("--noise", type=float, default=0.0, help="PV noise SD, PV units (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--duration", type=float, default=None, help="seconds (default: scenario's)")
    p.add_argument("-o", "--output", required=True, type=Path, help="CSV file to write")
    p.add_argument("--step-test", metavar="HOLD_S", type=float, default=None,
                   help="a step test instead: the loop in manual, OP playing the default "
                   "sequence (stiction.valvetest.step_test_levels) from 50 %%, each level held "
                   "HOLD_S seconds; writes t, op, pv, vp (the valve position), for "
                   "`stiction valve-test`")
    p.add_argument("--historian", metavar="TAG", default=None,
                   help="write OP and PV as a process historian exports them instead: "
                   "columns Timestamp;TAG.OP;TAG.PV, ';'-separated with decimal commas, ISO "
                   "time stamps from 2024-03-01 06:00:00 (UTC), and PV marked 'I/O Timeout' "
                   "every 500th row from row 250 (a scan the historian could not read)")
    p.set_defaults(handler=_cmd_simulate)


def _cmd_plant(args: argparse.Namespace) -> int:
    """``--plant NAME``: the named plant simulated, written as a wide CSV export."""
    extra = [param_option(k) for k in _SIM_PARAMS if k != "ts" and getattr(args, k) is not None]
    extra += ["--historian"] if args.historian is not None else []
    extra += ["--noise"] if args.noise else []
    if extra:
        raise UsageError(f"--plant takes --duration, --ts and --seed only, not {extra[0]}")
    ts = 1.0 if args.ts is None else args.ts
    if ts < 1.0 or ts != round(ts):
        raise UsageError(f"--ts {ts:g}: a plant's export is sampled every whole second or more")
    duration = 7200.0 if args.duration is None else args.duration
    if not duration >= 10.0 * ts:
        raise UsageError(f"--duration {duration:g}: at least 10 samples (10 x --ts)")
    sc = NAMED_PLANTS[args.plant]
    (rec,) = simulate_plants([sc], duration=duration, sample=round(ts), seed=args.seed)
    names = list(rec.op)
    columns = [f"{n}.{k}" for n in names for k in ("OP", "PV")] + list(rec.indicators)
    series = [x for n in names for x in (rec.op[n], rec.pv[n])] + list(rec.indicators.values())
    t = np.arange(series[0].size) * rec.ts
    try:
        with args.output.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t", *columns])
            w.writerows(np.round(np.column_stack([t, *series]), 6).tolist())
    except OSError as exc:
        raise UsageError(f"cannot write {args.output}: {exc.strerror}") from exc
    print(f"wrote {t.size} samples ({t[-1] + rec.ts:g} s, every {rec.ts:g} s) of plant "
          f"{sc.name} ({sc.description}) to {args.output}: {len(names)} loops, "
          f"{len(rec.indicators)} indicator{'' if len(rec.indicators) == 1 else 's'}; try: "
          f"stiction plant {args.output}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    if args.plant is not None:
        return _cmd_plant(args)
    overrides = {k: getattr(args, k) for k in _SIM_PARAMS if getattr(args, k) is not None}
    sc = scenario(args.scenario, **overrides)
    if args.step_test is not None:
        res = _step_test(sc, args)
        head, data = ["t", "op", "pv", "vp"], np.column_stack([res.t, res.op, res.pv, res.vp])
    else:
        res = simulate(sc, duration=args.duration, noise=args.noise, seed=args.seed)
        head = ["t", "sp", "op", "pv", "vp"]
        data = np.column_stack([res.t, res.sp, res.op, res.pv, res.vp])
    try:
        with args.output.open("w", newline="") as fh:
            if args.historian is not None:
                write_export(fh, args.historian, res.t, res.op, res.pv)
            else:
                w = csv.writer(fh)
                w.writerow(head)
                w.writerows(np.round(data, 9).tolist())
    except OSError as exc:
        raise UsageError(f"cannot write {args.output}: {exc.strerror}") from exc
    sticky = f"fs {sc.fs:g}, fd {sc.fd:g}, K {sc.k:g}" if sc.sticky else "perfect valve"
    print(f"wrote {len(res.t)} samples ({res.t[-1] + sc.ts:g} s, Ts {sc.ts:g} s) of scenario "
          f"{sc.name} ({sticky}, noise SD {args.noise:g}) to {args.output}")
    return 0


def _step_test(sc: Scenario, args: argparse.Namespace) -> SimResult:
    """The scenario's valve and process step-tested in manual (no controller)."""
    hold = round(args.step_test / sc.ts)
    if hold < 5:
        raise UsageError(f"--step-test: {args.step_test:g} s holds fewer than 5 samples of "
                         f"{sc.ts:g} s")
    run = simulate_step_test(sc.valve(), step_test_levels(), hold=hold, ts=sc.ts, kp=sc.kp,
                             tau=sc.tau, theta=sc.theta, integrating=sc.integrating,
                             noise_sd=args.noise, seed=args.seed)
    return SimResult(run.t, np.full(run.t.size, np.nan), run.op[0], run.pv[0], run.vp[0], sc)


# ----------------------------------------------------------------------------- signature
def add_signature(sub: Subparsers) -> None:
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
        plt = pyplot()
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
