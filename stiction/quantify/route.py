"""Which sizing applies to a window called sticky: the He-Wang reading of a clean limit
cycle first, then the sticky valve fitted to PV, then the OP-PV ellipse's band, then the
fitted valve where its fit did not decide; unsized, why."""

from __future__ import annotations

import dataclasses

from .._validate import FloatArray
from ..signal.cycle import MIN_CYCLES, Cycle
from ..signal.oscillation import MIN_PERIOD
from .hewang import Quantification, quantify

__all__ = ["FittedValve", "Size", "limit_cycle", "size_valve"]


def limit_cycle(cycle: Cycle, n: int) -> bool:
    """A cycle the He-Wang quantification can read: slow enough to see the jumps and long
    enough to average over."""
    return cycle.period is not None and cycle.period >= MIN_PERIOD and \
        n / cycle.period >= MIN_CYCLES


@dataclasses.dataclass(frozen=True)
class Size:
    """The size of a sticky valve in OP units and how it was found (``method``)."""

    fd_op: float | None
    fs_op: float | None
    jump_op: float | None
    cycles: int
    method: str
    multi_jump: bool = False
    warnings: tuple[str, ...] = ()
    quant: Quantification | None = None


@dataclasses.dataclass(frozen=True)
class FittedValve:
    """The He-Wang valve fitted to PV (the Hammerstein fit): fd, fs in OP units, and whether
    the fit voted stiction (``decided``) or did not decide (a fit that voted against is no
    FittedValve)."""

    fd: float
    fs: float | None
    decided: bool


def size_valve(op: FloatArray, pv: FloatArray, cycle: Cycle, *, quant: Quantification | None,
               ts: float, kp: float | None, delay: float, integrating: bool, k: float,
               pv_noise: float, fitted_valve: FittedValve | None,
               ellipse_band: float | None) -> Size:
    """fd (and fs, with kp) in OP units, by the first method that applies: the OP at the PV
    jumps of a clean limit cycle (He & Wang 2014), the He-Wang valve fitted to PV where that
    fit says stiction, half the apparent stiction band of the OP-PV ellipse (Choudhury et
    al. 2006), the fitted valve where the fit does not decide. A cycle in which the valve
    jumps more than once per half cycle is no limit cycle to read, nor an ellipse to read
    (the same cycle): only the fitted valve, which models the whole window, sizes it.
    Stick-slip episodes without a cycle are not sized: one episode's OP travel says how far
    OP went before this slip, not the band. Unsized, ``method`` says why."""
    why = "no limit cycle to read the jumps from"
    multi = False
    warn: tuple[str, ...] = ()
    if limit_cycle(cycle, op.size):
        assert cycle.period is not None
        if quant is None:
            quant = quantify(op, pv, period=cycle.period, ts=ts, kp=kp, delay=delay,
                             integrating=integrating, k=k, pv_noise=pv_noise)
        warn = quant.warnings
        multi = quant.multi_jump
        if quant.reason is not None:
            why = quant.reason
        elif multi:
            # not a pure stick-slip cycle: no size from its jumps is better than a wrong one
            why = ("the valve jumps more than once per half cycle, so the cycle is not one "
                   "stick-slip limit cycle to size")
        elif quant.poor_fit:
            why = (f"PV between the jumps does not follow one valve jump's response in "
                   f"{quant.poor_fit} half cycles")
        elif quant.fd_op is not None and quant.fd_op > 0:
            return Size(quant.fd_op, quant.fs_op, quant.jump_op, quant.cycles_used,
                         f"from OP at the PV jumps over {quant.cycles_used} cycles "
                         "(He & Wang 2014)", multi, warn, quant)
    fitted = fitted_valve
    if fitted is not None and fitted.decided:
        return Size(fitted.fd, fitted.fs if kp is not None else None, None, 0,
                    f"from the He-Wang valve fitted to PV ({why})", multi, warn, quant)
    if ellipse_band is not None and not multi:
        return Size(ellipse_band / 2.0, None, None, 0, "half the apparent stiction band of the "
                    f"OP-PV ellipse (Choudhury et al. 2006; {why})", multi, warn, quant)
    if fitted is not None:
        return Size(fitted.fd, fitted.fs if kp is not None else None, None, 0,
                    "from the He-Wang valve fitted to PV, though the fit does not decide "
                    f"between a sticky and a linear valve ({why})", multi, warn, quant)
    return Size(None, None, None, 0, why, multi, warn, quant)
