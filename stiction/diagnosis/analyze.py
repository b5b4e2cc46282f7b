"""``analyze``: one window of OP/PV in, one :class:`~stiction.Assessment` out.

The path of a window: the data-quality gates (:mod:`.quality`, :mod:`.responding`); the
cycle (:func:`stiction.signal.cycle.find_cycle`); whether the window holds enough of its loop
to judge (:mod:`.enough`); every registered detector (:mod:`.evidence`,
:mod:`stiction.detectors.registry`) and the OP-PV shape network (:mod:`.network`); one
confidence from what the tests saw (:mod:`.features`, the learned :mod:`.model`); the call
from the network and the decision (:mod:`.call`), stiction only where a test or the network
says so (the evidence gate, :mod:`.gate`); when it says stiction, the size
(:mod:`stiction.quantify.route`); the reason in words (:mod:`.reasons`). A window found calm
in which a live PV held within its noise while OP ramped on is a valve not responding
(:func:`.responding.held_while_op_ran`); one too short to judge is ``bad_data``, saying what
would be enough.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from numpy.typing import ArrayLike

from .._assessment import Assessment, Verdict
from .._validate import FloatArray
from ..detectors.ellipse import EllipseFit
from ..detectors.hammerstein import HammersteinFit
from ..quantify.hewang import Quantification, quantify
from ..quantify.route import FittedValve, limit_cycle, size_valve
from ..quantify.travel import Travel, measure_travel
from ..signal.cycle import Cycle, find_cycle
from . import model as learned
from . import network
from .adapt import ADAPTED, Site, at_site, at_site_evidence
from .arguments import PROCESSES, along, validate
from .call import call, shipped
from .enough import SEE_CYCLES, movement_scales, too_short
from .evidence import Findings, gather
from .features import features
from .quality import check_quality
from .reasons import decision_evidence, not_called, size_text, stiction_head, too_fast_to_see
from .responding import held_while_op_ran
from .setpoint import SetpointCut, steady_stretch
from .travel import apply_travel, frozen_reading

__all__ = ["PROCESSES", "Details", "analyze", "analyze_details"]

@dataclasses.dataclass(frozen=True)
class Details:
    """The assessment plus the intermediate results (for plots and the reproduce table)."""

    assessment: Assessment
    op: FloatArray | None = None  # the cleaned window
    pv: FloatArray | None = None
    quantification: Quantification | None = None
    cycle: Cycle | None = None
    findings: Findings | None = None
    parts: Mapping[str, float] | None = None  # what weighed in the decision (reasons.weighed)
    start: int = 0  # index of op[0] in the caller's window (a leading gap trimmed)
    travel: Travel | None = None  # what the valve's position said, where it was given


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
    position: ArrayLike | None = None,
    sp: ArrayLike | None = None,
    site: Site | None = None,
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
    position
        The valve's position as its positioner reports it, in OP units (% of span when OP
        is), sampled with OP; optional. Where it is usable, stiction is measured from OP
        against the valve's travel (:mod:`stiction.quantify.travel`: the band, the slip,
        and fd, fs from them) and that decides the verdict (:mod:`.travel`: ``stiction``,
        ``no_stiction`` for a valve that follows OP whatever PV does,
        ``valve_not_responding``); where it is not (all NaN, too gappy, a valve that never
        reversed) the verdict is OP and PV's, as without it. The evidence ``travel`` says
        which source decided.
    sp
        The loop's setpoint, sampled with OP; optional. Where it steps, the window is judged
        on its longest stretch between the steps, never across one (a setpoint step is not
        the valve's jump: :mod:`.setpoint`), and the reason says which samples; a setpoint
        that moves continuously (a cascade's) leaves the window whole, with a warning.
    site
        The share of sticky valves at the loop's site (:class:`stiction.diagnosis.adapt.Site`:
        :func:`~stiction.diagnosis.adapt.site_of` a batch's first assessments, a gateway's
        previous round); optional. The OP-PV shape network's probability is moved to it
        before the call (``site`` ``"adapted"`` in the assessment); without it the window
        is scored at the simulation's share (``site`` ``"none"``).

    Returns
    -------
    Assessment
        ``verdict`` with a one-sentence ``reason``; sizes only when the verdict is
        ``stiction``. A window too short to judge (fewer than 64 samples, or, without a
        cycle, no more than about one of its own movements: :mod:`.enough`) is
        ``bad_data``, its reason saying how long would be enough.

    Raises
    ------
    ParameterError
        An argument is unusable (non-numeric data, unequal lengths, ts <= 0, ...).
    """
    return analyze_details(op, pv, ts=ts, kp=kp, delay=delay, process=process,
                           op_range=op_range, k=k, position=position, sp=sp,
                           site=site).assessment


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
    position: ArrayLike | None = None,
    sp: ArrayLike | None = None,
    site: Site | None = None,
) -> Details:
    """:func:`analyze` with its intermediate results. ``force_quantify`` runs the
    quantification even when detection does not say stiction (as the paper's Table 6 does
    for every row); the verdict is unchanged and the sizes are then left out of the
    assessment but available in ``Details.quantification``. ``position``, ``sp``, ``site``:
    as for :func:`analyze` (``Details.start`` is then the judged stretch's first sample)."""
    op_a, pv_a, ts_, kp_, delay_, span, k_ = validate(
        op, pv, ts=ts, kp=kp, delay=delay, process=process, op_range=op_range, k=k)
    pos_a = along("position", position, op_a.size)
    sp_a = along("sp", sp, op_a.size)
    cut = None if sp_a is None else steady_stretch(sp_a, pv_a)
    if cut is not None and cut.cuts:
        op_a, pv_a = op_a[cut.start:cut.stop], pv_a[cut.start:cut.stop]
        pos_a = None if pos_a is None else pos_a[cut.start:cut.stop]
    d = _judged(op_a, pv_a, pos_a, ts=ts_, kp=kp_, delay=delay_, span=span, k=k_,
                integrating=process == "integrating", force_quantify=force_quantify,
                site=site)
    return d if cut is None else _cut_said(d, cut, ts_)


def _cut_said(d: Details, cut: SetpointCut, ts: float) -> Details:
    """``d`` of the stretch ``cut`` chose, its reason (or, for a moving setpoint, its
    warnings) saying so."""
    a = d.assessment
    if not cut.cuts and not cut.short:
        a = dataclasses.replace(a, warnings=(*a.warnings, cut.sentence(ts)))
        return dataclasses.replace(d, assessment=a)
    said = cut.sentence(ts)
    sep = " " if a.reason.endswith(".") else ". "
    a = dataclasses.replace(a, reason=f"{a.reason}{sep}{said[0].upper()}{said[1:]}.")
    return dataclasses.replace(d, assessment=a, start=d.start + cut.start)


def _judged(op_a: FloatArray, pv_a: FloatArray, pos_a: FloatArray | None, *, ts: float,
            kp: float | None, delay: float, span: float | None, k: float, integrating: bool,
            force_quantify: bool, site: Site | None) -> Details:
    """The diagnosis of one stretch: OP and PV's, then the valve's travel where a position
    was given."""
    d = _op_pv(op_a, pv_a, ts=ts, kp=kp, delay=delay, span=span, k=k,
               integrating=integrating, force_quantify=force_quantify, site=site)
    if pos_a is None:
        return d
    travel = frozen_reading(measure_travel(op_a, pos_a, k=k, span=span), pv_a)
    return dataclasses.replace(d, assessment=apply_travel(d.assessment, travel, span=span,
                                                          k=k), travel=travel)


def _op_pv(op_a: FloatArray, pv_a: FloatArray, *, ts: float, kp: float | None, delay: float,
           span: float | None, k: float, integrating: bool, force_quantify: bool,
           site: Site | None) -> Details:
    """The diagnosis from OP and PV alone (the module's path)."""
    q = check_quality(op_a, pv_a, span)
    warnings = tuple(q.warnings)
    if q.not_responding is not None:
        return Details(Assessment(Verdict.VALVE_NOT_RESPONDING, q.not_responding.reason(
            q.op.size), warnings=warnings), q.op, q.pv, start=q.start)
    if q.reason is not None:
        return Details(Assessment(Verdict.BAD_DATA, q.reason, warnings=warnings))
    op_c, pv_c = q.op, q.pv
    cycle = find_cycle(op_c, pv_c, integrating=integrating)
    # the window's own cycle passed the ACF's test of enough cycles: only what has no cycle
    # (or too few samples) is too short here
    short = too_short(op_c.size, scales=None if cycle.cycling else movement_scales(op_c, pv_c))
    if short is not None and short.withdraws(Verdict.STICTION):  # too short for any verdict
        return Details(Assessment(Verdict.BAD_DATA, short.reason(ts), warnings=warnings),
                       op_c, pv_c, cycle=cycle, start=q.start)
    found = network.added(gather(op_c, pv_c, cycle, integrating=integrating, ts=ts),
                          op_c, pv_c, cycle)
    d = dataclasses.replace(_decide(
        op_c, pv_c, cycle, found, ts=ts, kp=kp, delay=delay, span=span, k=k,
        integrating=integrating, force_quantify=force_quantify, warnings=warnings,
        site=site), start=q.start)
    if d.assessment.verdict == Verdict.NOT_OSCILLATING and (
            held := held_while_op_ran(op_c, pv_c, span=span)) is not None:  # stuck, not calm
        a = Assessment(Verdict.VALVE_NOT_RESPONDING, held.reason(op_c.size),
                       warnings=warnings, evidence=d.assessment.evidence)
        return dataclasses.replace(d, assessment=a)
    if short is not None and short.withdraws(d.assessment.verdict):  # a part of a slow cycle
        a = dataclasses.replace(d.assessment, verdict=Verdict.BAD_DATA,
                                reason=short.reason(ts), confidence=None)
        return dataclasses.replace(d, assessment=a)
    return d


def _decide(op_c: FloatArray, pv_c: FloatArray, cycle: Cycle, found: Findings, *, ts: float,
            kp: float | None, delay: float, span: float | None, k: float, integrating: bool,
            force_quantify: bool, warnings: tuple[str, ...], site: Site | None) -> Details:
    """The learned decision on a clean window's evidence, the size and the reason."""
    model = learned.load()
    x = features(found.evidence, found.results, cycle, op=op_c, pv=pv_c,
                 integrating=integrating)
    dec = model.probability(x)
    parts = model.contributions(x)
    reading = found.results.get(network.NAME)
    net = reading.probability if isinstance(reading, network.Reading) else None
    if site is not None and net is not None:  # the network's probability at the site's share
        net = at_site(net, site)
    at = shipped()
    c = call(dec, net, {e.test: e.vote for e in found.evidence if e.test != network.NAME},
             too_fast=too_fast_to_see(cycle), at=at)
    evidence = (*(e if site is None or net is None else at_site_evidence(e, net)
                  for e in found.evidence),
                decision_evidence(dec, at.stiction_at, at.no_stiction_at))
    si_test = "si_pv" if integrating else "si_op"
    si = next(e.value for e in found.evidence if e.test == si_test)
    base: dict[str, Any] = {
        "oscillating": cycle.regular,
        "period_s": None if cycle.period is None else cycle.period * ts,
        "stiction_index": si, "confidence": c.confidence, "evidence": evidence,
        **({} if site is None else {"site": ADAPTED, "site_share": site.share})}
    quant: Quantification | None = None
    if force_quantify and limit_cycle(cycle, op_c.size):
        quant = quantify(op_c, pv_c, period=cycle.period or 0.0, ts=ts, kp=kp,
                         delay=delay, integrating=integrating, k=k, pv_noise=found.noise[1])

    if c.verdict != Verdict.STICTION:
        verdict, reason = not_called(c, cycle, evidence, parts, at=at,
                                     reach_s=op_c.size / SEE_CYCLES * ts)
        return Details(Assessment(verdict, reason, warnings=warnings, **base),
                       op_c, pv_c, quant, cycle, found, parts)
    size = size_valve(op_c, pv_c, cycle, quant=quant, ts=ts, kp=kp, delay=delay,
                      integrating=integrating, k=k, pv_noise=found.noise[1],
                      fitted_valve=_fitted_valve(found), ellipse_band=_ellipse_band(found),
                      span=span)
    warnings = (*warnings, *size.warnings)
    head = stiction_head(c.confidence, evidence, parts, cycle)
    if size.fd_op is None:
        return Details(Assessment(Verdict.STICTION, f"{head} {unsized(size.method, found)}",
                                  multi_jump=size.multi_jump, warnings=warnings, **base),
                       op_c, pv_c, size.quant, cycle, found, parts)
    scale, unit = (1.0, "OP units") if span is None else (span / 100.0, "% of span")

    def frac(x: float | None) -> float | None:
        return None if x is None or span is None else x / span

    text = size_text(size.fd_op / scale, None if size.fs_op is None else size.fs_op / scale,
                     unit, size.method, need_kp=size.fs_op is None and kp is None)
    return Details(Assessment(
        Verdict.STICTION, head + text,
        fd=frac(size.fd_op), fs=frac(size.fs_op), jump=frac(size.jump_op),
        fd_op=size.fd_op, fs_op=size.fs_op, cycles_used=size.cycles,
        multi_jump=size.multi_jump, warnings=warnings, **base), op_c, pv_c, size.quant,
        cycle, found, parts)


def _fitted_valve(found: Findings) -> FittedValve | None:
    """The He-Wang valve fitted to PV, where that fit found one (fd > 0) and does not say a
    linear valve explains PV as well."""
    ham = found.results["hammerstein"]
    vote = found.vote("hammerstein")
    if isinstance(ham, HammersteinFit) and vote >= 0 and ham.fd is not None and ham.fd > 0:
        return FittedValve(ham.fd, ham.fs, decided=vote > 0)
    return None


def unsized(why: str, found: Findings) -> str:
    """The sentence of a sticky valve not sized: why the limit cycle did not size it, and
    why the valve fitted to PV did not (the fit's own words)."""
    ham = next(e for e in found.evidence if e.test == "hammerstein")
    fit = ham.note if ham.vote >= 0 else f"{ham.note}, so it gives no size"
    return f"Size: not sized, {why}; the valve fitted to PV: {fit}."


def _ellipse_band(found: Findings) -> float | None:
    """The OP-PV ellipse's apparent stiction band, where the ellipse does not say otherwise."""
    ell = found.results["ellipse"]
    if isinstance(ell, EllipseFit) and ell.band is not None and ell.band > 0 and \
            found.vote("ellipse") >= 0:
        return ell.band
    return None
