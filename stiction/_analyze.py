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

from ._assessment import Assessment, Evidence, Verdict
from ._combine import NO_STICTION_CONFIDENCE, STICTION_CONFIDENCE, confidence
from ._errors import ParameterError
from ._evidence import MIN_CYCLES, Cycle, Findings, find_cycle, gather
from ._oscillation import MIN_PERIOD
from ._quality import check_quality
from ._quantify import Quantification, quantify
from ._validate import FloatArray

__all__ = ["PROCESSES", "Details", "analyze", "analyze_details"]

PROCESSES = ("self-regulating", "integrating")


@dataclasses.dataclass(frozen=True)
class Details:
    """The assessment plus the intermediate results (for plots and the reproduce table)."""

    assessment: Assessment
    op: FloatArray | None = None  # the cleaned window
    pv: FloatArray | None = None
    quantification: Quantification | None = None
    cycle: Cycle | None = None
    findings: Findings | None = None


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
    cycle = find_cycle(op_c, pv_c, integrating=integrating)
    found = gather(op_c, pv_c, cycle, integrating=integrating, ts=ts_)
    conf = confidence(found.evidence)
    si_test = "si_pv" if integrating else "si_op"
    si = next(e.value for e in found.evidence if e.test == si_test)
    base: dict[str, Any] = {
        "oscillating": cycle.regular,
        "period_s": None if cycle.period is None else cycle.period * ts_,
        "stiction_index": si, "confidence": conf, "evidence": found.evidence}
    quant: Quantification | None = None
    if force_quantify and _limit_cycle(cycle, op_c.size):
        quant = quantify(op_c, pv_c, period=cycle.period or 0.0, ts=ts_, kp=kp_,
                         delay=delay_, integrating=integrating, k=k_, pv_noise=found.noise[1])

    if conf < STICTION_CONFIDENCE:
        verdict, reason = _not_stiction(cycle, found.evidence, conf)
        return Details(Assessment(verdict, reason, warnings=tuple(warnings), **base),
                       op_c, pv_c, quant, cycle, found)

    size = _size(op_c, pv_c, cycle, found, quant=quant, ts=ts_, kp=kp_, delay=delay_,
                 integrating=integrating, k=k_)
    warnings.extend(size.warnings)
    said = _said(found.evidence, 1)
    head = f"stiction (confidence {conf:.2f}; {said})"
    if size.fd_op is None:
        return Details(Assessment(Verdict.STICTION, f"{head}; not sized: {size.method}",
                                  multi_jump=size.multi_jump, warnings=tuple(warnings), **base),
                       op_c, pv_c, size.quant, cycle, found)
    scale = 1.0 if span is None else span
    unit = "of span" if span is not None else "in OP units (give op_range for fractions of span)"
    fs_txt = "" if size.fs_op is None else f", fs {size.fs_op / scale:.4g}"
    no_kp = "" if size.fs_op is not None or kp_ is not None else " (fs needs kp)"

    def frac(x: float | None) -> float | None:
        return None if x is None or span is None else x / span

    return Details(Assessment(
        Verdict.STICTION,
        f"{head}; fd {size.fd_op / scale:.4g}{fs_txt} {unit}, {size.method}{no_kp}",
        fd=frac(size.fd_op), fs=frac(size.fs_op), jump=frac(size.jump_op),
        fd_op=size.fd_op, fs_op=size.fs_op, cycles_used=size.cycles,
        multi_jump=size.multi_jump, warnings=tuple(warnings), **base), op_c, pv_c, size.quant,
        cycle, found)


def _limit_cycle(cycle: Cycle, n: int) -> bool:
    """A cycle the He-Wang quantification can read: slow enough to see the jumps and long
    enough to average over."""
    return cycle.period is not None and cycle.period >= MIN_PERIOD and \
        n / cycle.period >= MIN_CYCLES


def _said(evidence: tuple[Evidence, ...], vote: int) -> str:
    names = [e.test for e in evidence if e.vote == vote]
    if not names:
        return "no test says so" if vote > 0 else "no test says otherwise"
    first = next(e.note for e in evidence if e.vote == vote)
    word = "for" if vote > 0 else "against"
    return f"{word}: {', '.join(names)} ({first})"


def _not_stiction(cycle: Cycle, evidence: tuple[Evidence, ...], conf: float
                  ) -> tuple[Verdict, str]:
    """Verdict and reason when the confidence stays under the stiction threshold."""
    voted = [e for e in evidence if e.vote]
    if not cycle.regular and conf <= 0.5:
        src = cycle.pv if cycle.source == "PV" else cycle.op
        what = src.osc.reason if not cycle.cycling else (
            f"a cycle of {cycle.period or 0:.0f} samples, but irregular "
            f"(regularity {src.osc.regularity:.2f} <= 1)")
        return Verdict.NOT_OSCILLATING, (f"no regular oscillation in OP or PV ({what}); "
                                         f"confidence of stiction {conf:.2f}")
    if conf <= NO_STICTION_CONFIDENCE:
        return Verdict.NO_STICTION, (f"not stiction (confidence {conf:.2f}; "
                                     f"{_said(evidence, -1)})")
    fast = ""
    if cycle.period is not None and cycle.period < MIN_PERIOD:
        fast = (f"; the cycle of {cycle.period:.1f} samples is too fast to see its shape: "
                "sample faster")
    if not voted:
        return Verdict.UNDETERMINED, (f"no test can tell on this window (confidence "
                                      f"{conf:.2f}){fast}")
    return Verdict.UNDETERMINED, (f"the tests disagree or are weak (confidence {conf:.2f}; "
                                  f"{_said(evidence, 1)}; {_said(evidence, -1)}){fast}")


@dataclasses.dataclass(frozen=True)
class _Size:
    fd_op: float | None
    fs_op: float | None
    jump_op: float | None
    cycles: int
    method: str
    multi_jump: bool = False
    warnings: tuple[str, ...] = ()
    quant: Quantification | None = None


def _size(op: FloatArray, pv: FloatArray, cycle: Cycle, found: Findings, *,
          quant: Quantification | None, ts: float, kp: float | None, delay: float,
          integrating: bool, k: float) -> _Size:
    """fd (and fs, with kp) in OP units, by the first method that applies: the OP at the PV
    jumps of a clean limit cycle (He & Wang 2014), the He-Wang valve fitted to PV (when
    that fit says stiction), half the apparent stiction band of the OP-PV ellipse
    (Choudhury et al. 2006). Stick-slip episodes without a cycle are not sized: one
    episode's OP travel says how far OP went before this slip, not the band."""
    why = "no limit cycle to read the jumps from"
    multi = False
    warn: tuple[str, ...] = ()
    if _limit_cycle(cycle, op.size):
        assert cycle.period is not None
        if quant is None:
            quant = quantify(op, pv, period=cycle.period, ts=ts, kp=kp, delay=delay,
                             integrating=integrating, k=k, pv_noise=found.noise[1])
        warn = quant.warnings
        multi = quant.multi_jump
        if quant.reason is not None:
            why = quant.reason
        elif multi:
            # not a pure stick-slip cycle: no size is better than a wrong one (the other
            # methods read the same cycle)
            return _Size(None, None, None, quant.cycles_used,
                         "the valve jumps more than once per half cycle, so the cycle is not "
                         "one stick-slip limit cycle to size", multi, warn, quant)
        elif quant.poor_fit:
            why = (f"PV between the jumps does not follow one valve jump's response in "
                   f"{quant.poor_fit} half cycles")
        elif quant.fd_op is not None and quant.fd_op > 0:
            return _Size(quant.fd_op, quant.fs_op, quant.jump_op, quant.cycles_used,
                         f"from OP at the PV jumps over {quant.cycles_used} cycles "
                         "(He & Wang 2014)", multi, warn, quant)
    ham = found.hammerstein
    if found.vote("hammerstein") > 0 and ham.fd is not None and ham.fd > 0:
        return _Size(ham.fd, ham.fs if kp is not None else None, None, 0,
                     f"from the He-Wang valve fitted to PV ({why})", multi, warn, quant)
    ell = found.ellipse
    if ell is not None and ell.band is not None and ell.band > 0 and \
            found.vote("ellipse") >= 0:
        return _Size(ell.band / 2.0, None, None, 0, "half the apparent stiction band of the "
                     f"OP-PV ellipse (Choudhury et al. 2006; {why})", multi, warn, quant)
    return _Size(None, None, None, 0, why, multi, warn, quant)
