"""Issue 35 item 4: sizes beyond 100 % of span are not published; the reason says which
input is inconsistent. A sticky level loop read as self-regulating with a kp (5c94178: fs
365 % and a jump of 714 % of span, no flag), an OP range narrower than the OP swing; and
`--process` has a help text."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from stiction import Assessment, Verdict, analyze
from stiction.cli import main
from stiction.quantify.route import size_valve
from stiction.scenarios import SimResult, scenario, simulate
from stiction.signal.cycle import find_cycle
from stiction.signal.noise import noise_sd


@functools.cache
def _loop(name: str, seed: int) -> SimResult:
    return simulate(scenario(name), noise=0.02, seed=seed)


def _sized(a: Assessment) -> list[float]:
    return [x for x in (a.fd, a.fs, a.jump) if x is not None]


def _size(r: SimResult, *, kp: float | None, span: float, integrating: bool = False,
          ) -> tuple[float | None, float | None, float | None, str]:
    op, pv = np.asarray(r.op), np.asarray(r.pv)
    size = size_valve(op, pv, find_cycle(op, pv, integrating=integrating), quant=None,
                      ts=1.0, kp=kp, delay=0.0, integrating=integrating, k=1.99,
                      pv_noise=noise_sd(pv), fitted_valve=None, ellipse_band=None, span=span)
    return size.fd_op, size.fs_op, size.jump_op, size.method


@pytest.mark.parametrize("name", ["table5-case1", "table5-case2"])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_level_read_as_self_regulating_is_not_sized(name: str, seed: int) -> None:
    """The sticky level valve's cycle read as self-regulating through kp 1: no size, and
    the reason names the likely cause (an integrating process read as self-regulating)
    and kp; read as what it is, with its own gain, it is sized inside the span. Whatever
    the verdict, analyze publishes nothing beyond the span (5c94178: fs 326-1224 %, jump
    636-2391 % of span, as `stiction`)."""
    r = _loop(name, seed)
    fd, fs, jump, why = _size(r, kp=1.0, span=100.0)
    assert (fd, fs, jump) == (None, None, None)
    assert "exceed the valve's whole span" in why
    assert "integrating process (a level) read as self-regulating" in why
    assert "check kp (1)" in why
    fd, fs, jump, _ = _size(r, kp=0.2, span=100.0, integrating=True)
    assert fd is not None and fs is not None and jump is not None
    assert 0.0 < fd <= fs <= 100.0 and 0.0 < jump <= 100.0
    a = analyze(r.op, r.pv, ts=1.0, kp=1.0, op_range=(0.0, 100.0))
    assert all(x <= 1.0 for x in _sized(a))
    assert a.verdict != Verdict.STICTION or "exceed the valve's whole span" in a.reason


@pytest.mark.parametrize("seed", [0, 1])
def test_an_op_range_narrower_than_the_swing_is_named(seed: int) -> None:
    """fd 27 % of a 0 .. 100 OP, told op_range 40 .. 60: fd would be 135 % of span."""
    r = _loop("table4-case2", seed)
    fd, _, _, why = _size(r, kp=None, span=20.0)
    assert fd is None and "fd 13" in why and "check op_range" in why
    assert _size(r, kp=None, span=100.0)[0] == pytest.approx(27.0, abs=2.0)
    a = analyze(r.op, r.pv, ts=1.0, op_range=(40.0, 60.0))
    assert all(x <= 1.0 for x in _sized(a))


def test_process_and_kp_are_explained(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["analyze", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "integrating: PV ramps while the valve is off balance (a level)" in out
    assert "PV units per s per OP unit" in out
