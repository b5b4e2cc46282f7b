"""``analyze``: one window of OP/PV in, one :class:`~stiction.Assessment` out.

Stages (each its own module): data-quality gates (:mod:`._quality`), oscillation detection
(:mod:`._oscillation`), stiction detection by curve fitting (:mod:`._detect`), and, only
when detection says stiction, PV switching points (:mod:`._switching`) and quantification
with the multi-jump check (:mod:`._quantify`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._assessment import Assessment, Verdict
from ._detect import NO_STICTION_SI, STICTION_SI, stiction_index
from ._errors import ParameterError
from ._oscillation import MIN_PERIOD, detect_oscillation
from ._quality import check_quality
from ._quantify import Quantification, quantify
from ._stickslip import stick_slip
from ._validate import FloatArray

__all__ = ["PROCESSES", "Details", "analyze", "analyze_details"]

PROCESSES = ("self-regulating", "integrating")
MIN_CYCLES = 2.5
"""Fewer periods than this in the window: too short to judge the shape reliably."""


@dataclasses.dataclass(frozen=True)
class Details:
    """The assessment plus the intermediate results (for plots and the reproduce table)."""

    assessment: Assessment
    op: FloatArray | None = None  # the cleaned window
    pv: FloatArray | None = None
    quantification: Quantification | None = None


def _series(name: str, value: ArrayLike) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "must be a sequence of numbers") from exc
    if arr.ndim != 1:
        raise ParameterError(name, f"must be one-dimensional, has {arr.ndim} dimensions")
    return arr


def _scalar(name: str, value: Any, *, positive: bool = False, non_negative: bool = False,
            non_zero: bool = False) -> float:
    if isinstance(value, bool):
        raise ParameterError(name, f"must be a number, was {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, f"must be a number, was {value!r}") from exc
    if not math.isfinite(v):
        raise ParameterError(name, f"must be finite, was {value!r}")
    if positive and v <= 0:
        raise ParameterError(name, f"must be > 0, was {value!r}")
    if non_negative and v < 0:
        raise ParameterError(name, f"must be >= 0, was {value!r}")
    if non_zero and v == 0:
        raise ParameterError(name, "must not be 0")
    return v


def _validate(
    op: ArrayLike, pv: ArrayLike, *, ts: Any, kp: Any, delay: Any, process: Any,
    op_range: Any, k: Any,
) -> tuple[FloatArray, FloatArray, float, float | None, float, float | None, float]:
    op_a = _series("op", op)
    pv_a = _series("pv", pv)
    if op_a.size != pv_a.size:
        raise ParameterError("pv", f"must have the same length as op ({pv_a.size} != "
                                   f"{op_a.size})")
    ts_ = _scalar("ts", ts, positive=True)
    kp_ = None if kp is None else _scalar("kp", kp, non_zero=True)
    delay_ = _scalar("delay", delay, non_negative=True)
    if process not in PROCESSES:
        raise ParameterError("process", f"must be one of {', '.join(PROCESSES)}; was "
                                        f"{process!r}")
    span: float | None = None
    if op_range is not None:
        try:
            lo, hi = op_range
        except (TypeError, ValueError) as exc:
            raise ParameterError("op_range", f"must be a pair (lo, hi), was {op_range!r}"
                                 ) from exc
        lo_ = _scalar("op_range", lo)
        hi_ = _scalar("op_range", hi)
        if hi_ <= lo_:
            raise ParameterError("op_range", f"must have lo < hi, was {op_range!r}")
        span = hi_ - lo_
    k_ = _scalar("k", k)
    if not 1.0 <= k_ <= 2.0:
        raise ParameterError("k", f"must lie in [1, 2], was {k!r}")
    return op_a, pv_a, ts_, kp_, delay_, span, k_


def _stick_slip_verdict(op: FloatArray, pv: FloatArray, warnings: list[str],
                        **base: Any) -> Assessment | None:
    """Verdict ``stiction`` (not sized) when a window without a usable limit cycle shows
    stick-slip episodes (:mod:`._stickslip`); None otherwise. Not sized: the He-Wang
    quantification rests on a limit cycle with one jump per half cycle."""
    ss = stick_slip(op, pv)
    if not ss.detected:
        return None
    e = max(ss.episodes, key=lambda ep: abs(ep.jump))
    count = len(ss.episodes)
    return Assessment(
        Verdict.STICTION,
        f"stick-slip without a limit cycle: {count} episode{'s' if count > 1 else ''} where "
        f"OP ramped (largest: {e.op_travel:+.3g} over {e.stuck} samples) with PV still, then "
        f"PV jumped ({e.jump:+.3g}) and OP did not; not sized (needs a limit cycle)",
        warnings=tuple(warnings), **base)


def analyze(
    op: ArrayLike,
    pv: ArrayLike,
    *,
    ts: float,
    kp: float | None = None,
    delay: float = 0.0,
    process: str = "self-regulating",
    op_range: tuple[float, float] | None = None,
    k: float = 1.99,
) -> Assessment:
    """Decide whether one window of a loop oscillates, whether stiction causes it, and size it.

    Parameters
    ----------
    op, pv
        Controller output (OP units, e.g. %) and process variable, equal-length 1-D
        sequences sampled every ``ts`` seconds. NaN/inf mark missing samples: short gaps
        (at most 10 % of the window in total, none longer than 2 % of it or 5 samples) are
        interpolated linearly and reported in ``warnings``; gaps at the ends are trimmed;
        a window with more or longer gaps gets verdict ``bad_data`` ("too gappy").
    ts
        Sample time, s.
    kp
        Process gain, PV units per OP unit (per second for an integrating process). Needed
        for ``fs``; without it only ``fd`` is estimated.
    delay
        Process dead time, s; the valve jumps are taken ``delay`` before the PV onsets.
    process
        ``"self-regulating"`` (detect on OP, fit exponentials to PV) or ``"integrating"``
        (detect on PV, fit ramps).
    op_range
        OP values of 0 % and 100 % valve span, ``(lo, hi)``. It only turns sizes into
        fractions of span (``fd``/``fs``/``jump`` = OP units / ``(hi - lo)``); no gate
        assumes any OP range. Without it ``fd``/``fs``/``jump`` stay None and the sizes are
        reported in OP units (``fd_op``/``fs_op``), as the reason says.
    k
        Overshoot factor K of He's model, in [1, 2]; 1.99 unless the valve is known.

    Returns
    -------
    Assessment
        ``verdict`` with a one-sentence ``reason``; sizes only when the verdict is
        ``stiction``.

    Raises
    ------
    ParameterError
        An argument is unusable (non-numeric data, unequal lengths, ts <= 0, ...).
    """
    return analyze_details(op, pv, ts=ts, kp=kp, delay=delay, process=process,
                           op_range=op_range, k=k).assessment


def analyze_details(
    op: ArrayLike,
    pv: ArrayLike,
    *,
    ts: float,
    kp: float | None = None,
    delay: float = 0.0,
    process: str = "self-regulating",
    op_range: tuple[float, float] | None = None,
    k: float = 1.99,
    force_quantify: bool = False,
) -> Details:
    """:func:`analyze` with its intermediate results. ``force_quantify`` runs the
    quantification even when detection does not say stiction (as the paper's Table 6 does
    for every row); the verdict is unchanged and the sizes are then left out of the
    assessment but available in ``Details.quantification``."""
    op_a, pv_a, ts_, kp_, delay_, span, k_ = _validate(
        op, pv, ts=ts, kp=kp, delay=delay, process=process, op_range=op_range, k=k)
    integrating = process == "integrating"
    q = check_quality(op_a, pv_a, span)
    warnings = list(q.warnings)
    if q.not_responding is not None:
        return Details(Assessment(Verdict.VALVE_NOT_RESPONDING, q.not_responding.reason(
            q.op.size), warnings=tuple(warnings)), q.op, q.pv)
    if q.reason is not None:
        return Details(Assessment(Verdict.BAD_DATA, q.reason, warnings=tuple(warnings)))
    op_c, pv_c = q.op, q.pv

    det_name, det = ("PV", pv_c) if integrating else ("OP", op_c)
    osc = detect_oscillation(det)
    if not osc.oscillating or osc.period is None:
        slip = _stick_slip_verdict(op_c, pv_c, warnings)
        if slip is not None:
            return Details(slip, op_c, pv_c)
        return Details(Assessment(Verdict.NOT_OSCILLATING, f"{det_name}: {osc.reason}",
                                  warnings=tuple(warnings)), op_c, pv_c)
    period = osc.period
    period_s = period * ts_
    if period < MIN_PERIOD:
        return Details(Assessment(
            Verdict.BAD_DATA, f"oscillation period {period:.1f} samples is too short to see "
            f"its shape (need {MIN_PERIOD:g}): sample faster", oscillating=True,
            period_s=period_s, warnings=tuple(warnings)), op_c, pv_c)
    cycles = op_c.size / period
    if cycles < MIN_CYCLES:
        return Details(Assessment(
            Verdict.BAD_DATA, f"window too short for the period: {cycles:.1f} cycles of "
            f"{period_s:.0f} s, need {MIN_CYCLES:g} (at least "
            f"{MIN_CYCLES * period_s:.0f} s)", oscillating=True, period_s=period_s,
            warnings=tuple(warnings)), op_c, pv_c)

    si = stiction_index(det, period)
    base: dict[str, Any] = {"oscillating": True, "period_s": period_s,
                            "stiction_index": si.si}
    quant: Quantification | None = None
    if si.si is None:
        slip = _stick_slip_verdict(op_c, pv_c, warnings, **base)
        if slip is not None:
            return Details(slip, op_c, pv_c)
        return Details(Assessment(Verdict.UNDETERMINED, f"too few clean half periods in {det_name} "
                                  f"to fit ({si.half_periods})", warnings=tuple(warnings),
                                  **base), op_c, pv_c)
    if not si.resolved or si.si < STICTION_SI:
        if force_quantify:
            quant = quantify(op_c, pv_c, period=period, ts=ts_, kp=kp_, delay=delay_,
                             integrating=integrating, k=k_)
        if not si.resolved:
            reason = (f"SI {si.si:.2f} not trusted: {det_name} is too noisy to tell a triangle "
                      "from a sine (both fit to within the noise); quantification not run")
            verdict = Verdict.UNDETERMINED
        elif si.si <= NO_STICTION_SI:
            reason = (f"SI {si.si:.2f} <= {NO_STICTION_SI}: {det_name} oscillates like a sine "
                      "(tuning or a disturbance, not stiction); quantification not run")
            verdict = Verdict.NO_STICTION
        else:
            reason = (f"SI {si.si:.2f} between {NO_STICTION_SI} and {STICTION_SI}: {det_name} "
                      "neither clearly triangular nor sinusoidal; quantification not run")
            verdict = Verdict.UNDETERMINED
        return Details(Assessment(verdict, reason, warnings=tuple(warnings), **base),
                       op_c, pv_c, quant)

    quant = quantify(op_c, pv_c, period=period, ts=ts_, kp=kp_, delay=delay_,
                     integrating=integrating, k=k_)
    warnings.extend(quant.warnings)
    if quant.reason is not None:
        return Details(Assessment(
            Verdict.STICTION, f"SI {si.si:.2f} >= {STICTION_SI}: stiction; not sized: "
            f"{quant.reason}", warnings=tuple(warnings), **base), op_c, pv_c, quant)
    assert quant.fd_op is not None  # set whenever reason is None
    if quant.multi_jump:
        return Details(Assessment(
            Verdict.UNDETERMINED, f"SI {si.si:.2f} looks like stiction, but the valve jumps "
            "more than once per half cycle: the cycle is not a pure stiction limit cycle "
            "(likely tuning), so it is not sized", multi_jump=True,
            cycles_used=quant.cycles_used, warnings=tuple(warnings), **base),
            op_c, pv_c, quant)
    if quant.poor_fit:
        return Details(Assessment(
            Verdict.UNDETERMINED, f"SI {si.si:.2f} looks like stiction, but PV between the "
            f"jumps does not follow one valve jump's response in {quant.poor_fit} half cycles "
            "(a load disturbance, or a creeping valve), so it is not called stiction and not "
            "sized", cycles_used=quant.cycles_used, warnings=tuple(warnings), **base),
            op_c, pv_c, quant)
    scale = 1.0 if span is None else span
    fs_txt = "" if quant.fs_op is None else f", fs {quant.fs_op / scale:.4g}"
    no_kp = "" if kp_ is not None else " (fs needs kp)"
    unit = "of span" if span is not None else "in OP units (give op_range for fractions of span)"

    def frac(x: float | None) -> float | None:
        return None if x is None or span is None else x / span

    return Details(Assessment(
        Verdict.STICTION,
        f"SI {si.si:.2f} >= {STICTION_SI}: stiction, fd {quant.fd_op / scale:.4g}{fs_txt} "
        f"{unit} over {quant.cycles_used} cycles{no_kp}",
        fd=frac(quant.fd_op), fs=frac(quant.fs_op), jump=frac(quant.jump_op),
        fd_op=quant.fd_op, fs_op=quant.fs_op, cycles_used=quant.cycles_used,
        warnings=tuple(warnings), **base), op_c, pv_c, quant)
