"""Reproduce He & Wang (2014) Tables 4-9: simulate every case, analyse it, compare.

Pure computation (no printing): :func:`reproduce` returns one :class:`ReproRow` per paper row;
the CLI's ``stiction reproduce`` prints them. Each case is analysed with
``force_quantify=True`` so that the sizes are available for every row, as in the paper's
tables, whatever our detector says; ``verdict`` is what :func:`stiction.analyze` returns.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import numpy as np

from .._assessment import Assessment
from ..diagnosis.analyze import analyze_details
from ..scenarios.named import SimResult, scenario, simulate
from .tables import PAPER_ROWS, PaperRow

__all__ = ["ReproRow", "error_pct", "qualifying_errors", "reproduce"]


@dataclasses.dataclass(frozen=True)
class ReproRow:
    paper: PaperRow
    assessment: Assessment
    fd: float | None  # our estimates, fractions of span (even when not stiction)
    fs: float | None
    multi_jump: bool
    true_jumps: int  # valve jumps in the simulation (the truth, from VP)
    true_multi_jump: bool  # over 10 % of consecutive simulated jumps go the same way

    @property
    def clean_limit_cycle(self) -> bool:
        """Did the simulated valve sit in the single-jump limit cycle the method assumes?"""
        return self.true_jumps >= 6 and not self.true_multi_jump

    @property
    def fd_err(self) -> float | None:
        return error_pct(self.fd, self.paper.fd_true)

    @property
    def fs_err(self) -> float | None:
        return error_pct(self.fs, self.paper.fs_true)


def error_pct(estimate: float | None, truth: float) -> float | None:
    return None if estimate is None else 100.0 * abs(estimate - truth) / truth


def reproduce(
    *, noise: float = 0.0, seed: int = 0, rows: Iterable[PaperRow] = PAPER_ROWS
) -> list[ReproRow]:
    """Simulate (default durations, PV noise SD ``noise``) and analyse every row."""
    cache: dict[tuple[str, tuple[tuple[str, object], ...]], SimResult] = {}
    out = []
    for row in rows:
        key = (row.scenario, row.overrides)
        if key not in cache:
            cache[key] = simulate(scenario(row.scenario, **dict(row.overrides)), noise=noise,
                                  seed=seed)
        res = cache[key]
        sc = res.scenario
        d = analyze_details(res.op, res.pv, ts=sc.ts, kp=row.kp, delay=row.delay,
                            op_range=(0.0, 100.0),
                            process="integrating" if sc.integrating else "self-regulating",
                            force_quantify=True)
        q = d.quantification
        fd = None if q is None or q.fd_op is None else q.fd_op / 100.0
        fs = None if q is None or q.fs_op is None else q.fs_op / 100.0
        jumps = np.diff(res.vp)[np.abs(np.diff(res.vp)) > 1e-9]
        same_way = bool(jumps.size > 1
                        and np.mean(np.sign(jumps[1:]) == np.sign(jumps[:-1])) > 0.1)
        out.append(ReproRow(row, d.assessment, fd, fs, bool(q is not None and q.multi_jump),
                            int(jumps.size), same_way))
    return out


def qualifying_errors(rows: Iterable[ReproRow]) -> tuple[list[float], list[float]]:
    """(paper's, ours) absolute % errors over every fd and fs where the paper's error is
    under 5 % (missing estimates count as 100 %), on rows whose simulated valve held the
    single-jump limit cycle (with noise, some runs stop cycling or jump twice)."""
    paper: list[float] = []
    ours: list[float] = []
    for r in rows:
        if not r.clean_limit_cycle:
            continue
        for p_err, o_err in ((r.paper.fd_err, r.fd_err), (r.paper.fs_err, r.fs_err)):
            if p_err < 5.0:
                paper.append(p_err)
                ours.append(100.0 if o_err is None else o_err)
    return paper, ours


def mean(x: list[float]) -> float:
    return float(np.mean(x)) if x else float("nan")
