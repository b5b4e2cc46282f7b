"""`stiction reproduce`: He & Wang (2014) Tables 4-9, the paper's figures beside ours."""

from __future__ import annotations

import argparse

import numpy as np

from .._errors import ParameterError
from ..paper.reproduce import mean, qualifying_errors, reproduce
from ._common import Subparsers


# ----------------------------------------------------------------------------- reproduce
def add_reproduce(sub: Subparsers) -> None:
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
