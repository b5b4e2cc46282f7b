"""Which sizing applies to a window called sticky: the He-Wang reading of a clean limit
cycle first, then the sticky valve fitted to PV, then the OP-PV ellipse's band, then the
fitted valve where its fit did not decide; unsized, why.

A size is physical or not published: no valve's friction or jump exceeds its whole span,
so where ``span`` (the OP range of 0 .. 100 % of span) is known, sizes beyond it are
withheld and the reason says which input is inconsistent (:func:`beyond_span`): the
process gain ``kp`` or the process type, through which the jump is read from PV, or the
OP range itself, against which the OP swing is read."""

from __future__ import annotations

import dataclasses

from .._validate import FloatArray
from ..signal.cycle import MIN_CYCLES, Cycle
from ..signal.oscillation import MIN_PERIOD
from .hewang import Quantification, quantify

__all__ = ["FittedValve", "Size", "beyond_span", "limit_cycle", "size_valve"]


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
               ellipse_band: float | None, span: float | None = None) -> Size:
    """:func:`first_size`, withheld where it exceeds ``span`` (:func:`beyond_span`)."""
    size = first_size(op, pv, cycle, quant=quant, ts=ts, kp=kp, delay=delay,
                      integrating=integrating, k=k, pv_noise=pv_noise,
                      fitted_valve=fitted_valve, ellipse_band=ellipse_band)
    why = beyond_span(size, span, cycle=cycle, kp=kp, integrating=integrating, ts=ts)
    if why is None:
        return size
    return Size(None, None, None, 0, why, size.multi_jump, size.warnings, size.quant)


def beyond_span(size: Size, span: float | None, *, cycle: Cycle, kp: float | None,
                integrating: bool, ts: float) -> str | None:
    """Why ``size`` cannot be the valve's (a figure beyond 100 % of ``span``), naming the
    input that is inconsistent; None where it fits (or no span is known). The jump (and fs,
    which holds it) is read from PV through ``kp``: too large a jump is ``kp`` too small, or
    an integrating process (a level) read as self-regulating, which reads PV's ramps
    between the jumps as a settling towards a far-off level (the half cycles' time
    constant then outlasts them). fd alone too large is the OP swing itself against
    ``span``: the OP range is wrong."""
    if span is None:
        return None
    figures = {"fd": size.fd_op, "fs": size.fs_op, "jump": size.jump_op}
    over = {k: 100.0 * v / span for k, v in figures.items() if v is not None and v > span}
    if not over:
        return None
    shown = ", ".join(f"{k} {v:.4g} %" for k, v in over.items())
    head = (f"the sizes read ({shown} of span) exceed the valve's whole span, so "
            "an input is inconsistent: ")
    if "fd" in over and size.fs_op is None:
        return head + ("the OP swing between the valve's jumps is wider than the OP range "
                       "given for 0 .. 100 % of span: check op_range (and OP's units)")
    sw = size.quant.switches if size.quant is not None else None
    half = None if cycle.period is None else cycle.period / 2.0
    if not integrating and sw is not None and sw.tau is not None and half is not None \
            and sw.tau > half:
        return head + (f"PV ramps between the jumps (its fitted time constant, "
                       f"{sw.tau * ts:.4g} s, outlasts the half cycle, {half * ts:.3g} s): "
                       "likely an integrating process (a level) read as self-regulating, so "
                       f"give process integrating, or check kp ({kp:g})")
    return head + (f"the valve's jump is read from PV through kp ({kp:g}), and kp is likely "
                   "wrong (too small, or for an integrating process not in PV units per s "
                   "per OP unit), or the process type is: check kp and process")


def first_size(op: FloatArray, pv: FloatArray, cycle: Cycle, *, quant: Quantification | None,
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
