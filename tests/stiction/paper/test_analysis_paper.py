"""Acceptance: He & Wang (2014) Tables 4-9 reproduced, without and with PV noise.

Noise level: white measurement noise of SD 0.05 PV units (kp = 1: 0.05 % of span), plus one
check at SD 0.1 for the Table 6 rows that matter most. With noise the simulated loop itself
sometimes leaves the single-jump limit cycle (Table 4 case 1 can stop cycling; slow Table 6
loops start jumping twice per half cycle, as in the paper's Figure 7): such rows (judged from
the simulated VP, not from our estimates) are held to "never confidently wrong" instead.

One row is exempt from "under 5 % where the paper was": Table 9 with kp told 0.6 (true 1).
Any estimator that reads J correctly must return fs = fd + (fs - fd) * 1 / 0.6 = 0.2133
(6.7 % high); the paper's 3.7 % there comes from its fs - fd being 10 % low throughout
Table 9 (0.195 - 0.177 = 0.018 instead of 0.020 at kp = 1), which happens to offset the
wrong gain. We require instead that our fs is within 0.5 % of that unbiased value.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from stiction import Verdict
from stiction.paper.reproduce import ReproRow, qualifying_errors, reproduce
from stiction.paper.tables import PAPER_ROWS


def _unbiased_fs(row: ReproRow) -> float:
    p = row.paper
    true_kp = 1.0 if p.table != 5 else 0.2
    return p.fd_true + (p.fs_true - p.fd_true) * true_kp / p.kp


def _exempt(row: ReproRow) -> bool:
    return abs(_unbiased_fs(row) / row.paper.fs_true - 1.0) >= 0.05


@functools.cache
def _reproduce(noise: float) -> list[ReproRow]:
    return reproduce(noise=noise, seed=1)


@pytest.fixture(scope="module", params=[0.0, 0.05], ids=["noise-free", "noise-0.05"])
def rows(request: pytest.FixtureRequest) -> list[ReproRow]:
    return _reproduce(request.param)


def test_every_paper_row_is_reproduced(rows: list[ReproRow]) -> None:
    assert len(rows) == len(PAPER_ROWS) == 4 + 14 + 7 + 7 + 16


FITTED_WITHIN = 0.20
"""How near the truth a size from the valve fitted to PV must be where the valve jumps more
than once per half cycle (no limit cycle's jumps to read: Table 6's slow loops, 7-15 %)."""


def _confidently_wrong(r: ReproRow) -> bool:
    """Wrong sizes given with a stiction verdict. Every paper row's valve is sticky, so a
    stiction verdict with no sizes at all (stick-slip seen, no limit cycle to size it from)
    is not wrong."""
    a = r.assessment
    if a.verdict != Verdict.STICTION:
        return False
    if a.fd is None and a.fs is None:
        return "not sized" not in a.reason
    if a.multi_jump and a.cycles_used == 0:  # sized from the valve fitted to PV (issue 28)
        return a.fd is None or abs(a.fd / r.paper.fd_true - 1) >= FITTED_WITHIN
    return (a.fd is None or abs(a.fd / r.paper.fd_true - 1) >= 0.05
            or (a.fs is not None and abs(a.fs / r.paper.fs_true - 1) >= 0.05 and not _exempt(r)))


def test_under_5_percent_where_the_paper_was(rows: list[ReproRow]) -> None:
    failures = []
    for r in rows:
        if not r.clean_limit_cycle:
            assert not _confidently_wrong(r), r
            continue
        if r.paper.fd_err < 5.0 and (r.fd_err is None or r.fd_err >= 5.0):
            failures.append(f"table {r.paper.table} {r.paper.case}: fd {r.fd} ({r.fd_err})")
        if r.paper.fs_err < 5.0:
            if _exempt(r):
                assert r.fs is not None
                assert r.fs == pytest.approx(_unbiased_fs(r), rel=0.005)
            elif r.fs_err is None or r.fs_err >= 5.0:
                failures.append(f"table {r.paper.table} {r.paper.case}: fs {r.fs} ({r.fs_err})")
    assert not failures, failures


def test_exemption_is_only_table9_kp_0_6(rows: list[ReproRow]) -> None:
    exempt = [r.paper.case for r in rows if r.paper.fs_err < 5.0 and _exempt(r)]
    assert exempt == ["kp told 0.6"]


def test_mean_error_no_larger_than_the_papers(rows: list[ReproRow]) -> None:
    paper, ours = qualifying_errors(rows)
    assert np.mean(ours) <= np.mean(paper)


@pytest.mark.parametrize("table", [4, 5, 6, 7, 8, 9])
def test_mean_error_per_table_noise_free(table: int) -> None:
    paper, ours = qualifying_errors(r for r in _reproduce(0.0) if r.paper.table == table)
    assert np.mean(ours) <= np.mean(paper)


def test_noise_free_simulations_hold_the_limit_cycle() -> None:
    assert all(r.clean_limit_cycle for r in _reproduce(0.0))


def _tau(r: ReproRow) -> float:
    return dict(r.paper.overrides).get("tau", 0.0)


def test_stiction_detected_where_the_paper_was_clear(rows: list[ReproRow]) -> None:
    """Every clean limit cycle of Tables 4, 5, 7, 8, 9 and Table 6 up to tau 300 s is
    called; Table 6's slower rows are held to less (the test below): the learned decision
    leaves some of them `undetermined`."""
    for r in rows:
        if not r.clean_limit_cycle or (r.paper.table == 6 and _tau(r) > 300.0):
            continue
        if r.paper.table in (4, 5, 7, 8, 9) or (r.paper.si is not None and r.paper.si >= 0.8):
            assert r.assessment.verdict == Verdict.STICTION, (r.paper.case, r.assessment)


@pytest.mark.parametrize("tau", [450.0, 480.0])
# noise-free (the seed changes nothing) and 0.05/1 are `rows` above, whose
# test_under_5_percent_where_the_paper_was checks these rows the same way
@pytest.mark.parametrize(("noise", "seed"), [(0.05, 2), (0.1, 1), (0.1, 2), (0.1, 3),
                                             (0.2, 3)])
def test_table6_slow_loops_never_confidently_wrong(tau: float, noise: float, seed: int) -> None:
    """Seeds where the noisy SI reaches the stiction band (>= 0.6) are among these: 0.05/1,
    0.05/2, 0.1/1, 0.1/2, 0.2/3 (SI 0.62-0.73 on at least one tau)."""
    rows = reproduce(noise=noise, seed=seed,
                     rows=[p for p in PAPER_ROWS if p.case == f"tau={tau:.0f}"])
    (r,) = rows
    a = r.assessment
    assert not _confidently_wrong(r), a
    if a.verdict == Verdict.STICTION and a.fd is None:
        assert "not sized" in a.reason
    if a.verdict != Verdict.STICTION:
        assert a.fd is None
        assert a.fs is None


SLOW_RUNS = ((0.0, 0), (0.05, 1), (0.05, 2))
SLOW_TAUS = (330.0, 360.0, 390.0)
UNDETERMINED_TODAY: dict[tuple[float, int, float], float] = {}
"""The runs left ``undetermined`` (their confidence), each marked ``xfail(strict=True)``: the
paper detects each, so the requirement stands and these fail it; the mark fails the day they
are called, so that it goes with them. At 3dfa8c7 the learned decision left four (0.80-0.82,
under its 0.87); since the OP-PV shape network (issue 36) every run is called, the network
reading them at 0.97-0.99 (its threshold 0.69)."""


@functools.cache
def _slow_rows(noise: float, seed: int) -> dict[float, ReproRow]:
    rows = reproduce(noise=noise, seed=seed,
                     rows=[p for p in PAPER_ROWS if p.case in ("tau=330", "tau=360", "tau=390")])
    return {_tau(r): r for r in rows}


@pytest.mark.parametrize(("noise", "seed"), SLOW_RUNS)
def test_table6_slow_loops_330_to_390_are_never_cleared_and_sized_when_called(
        noise: float, seed: int) -> None:
    """Table 6, tau 330-390 s (paper SI 0.84-0.64, detected): the slowest loops the paper
    still detects. The learned decision alone called some of them (0.89-0.99) and left the
    others `undetermined` at 0.80-0.82; with the OP-PV shape network (0.97-0.99) all are
    called. None is ever cleared, and what is called is sized within 5 %."""
    rows = _slow_rows(noise, seed)
    assert sorted(rows) == list(SLOW_TAUS)
    for r in rows.values():
        a = r.assessment
        assert a.verdict in (Verdict.STICTION, Verdict.UNDETERMINED), (r.paper.case, a.reason)
        assert a.confidence is not None and a.confidence >= 0.75, (r.paper.case, a.reason)
        if a.verdict != Verdict.STICTION:
            continue
        assert a.fd is not None
        assert a.fs is not None
        assert abs(a.fd / 0.18 - 1) < 0.05, (r.paper.case, a.fd)
        assert abs(a.fs / 0.20 - 1) < 0.05, (r.paper.case, a.fs)


@pytest.mark.parametrize(("noise", "seed", "tau"), [
    pytest.param(noise, seed, tau, marks=pytest.mark.xfail(
        strict=True, reason=f"undetermined at {UNDETERMINED_TODAY[(noise, seed, tau)]}"))
    if (noise, seed, tau) in UNDETERMINED_TODAY else (noise, seed, tau)
    for noise, seed in SLOW_RUNS for tau in SLOW_TAUS])
def test_table6_slow_loops_330_to_390_are_called(noise: float, seed: int, tau: float) -> None:
    """Each run of Table 6's slow loops is called `stiction` and sized within 5 %, as the
    paper detects each (issue 31: the test above would pass with every run
    `undetermined`). Today 5 of the 9 runs are; the 4 in UNDETERMINED_TODAY are not."""
    r = _slow_rows(noise, seed)[tau]
    a = r.assessment
    assert a.verdict == Verdict.STICTION, (r.paper.case, a.confidence, a.reason)
    assert a.fd is not None and abs(a.fd / 0.18 - 1) < 0.05, (r.paper.case, a.fd)
    assert a.fs is not None and abs(a.fs / 0.20 - 1) < 0.05, (r.paper.case, a.fs)
