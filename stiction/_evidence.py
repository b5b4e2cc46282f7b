"""Every test on one window, each kept with its value and its vote.

One test sees one signature of a sticky valve and fails somewhere else; their agreement is
the evidence (``../shared/docs/detection-methods.md``). :func:`find_cycle` finds the
oscillation the shape tests look at, :func:`gather` runs every test and returns one
:class:`~stiction.Evidence` per test, in :data:`TESTS` order:

``si_op``, ``si_pv``
    He et al. (2007) curve fitting on OP and on PV (:mod:`._detect`): triangle (+1, SI >=
    0.6) or sine (-1, SI <= 0.4), only when the shapes stand out of the noise. A sticky
    valve makes OP a triangle in a fast self-regulating loop and PV one in an integrating
    or slow loop: both are run whatever the process type, so a level loop analysed as
    self-regulating still shows its triangle.
``bicoherence``
    Choudhury et al. (2004) nonlinearity of PV (:mod:`._bicoherence`), on cycling windows
    only: it diagnoses an oscillation, and reads a set-point step's transient as
    nonlinear.
``horch``
    Horch (1999) odd or even OP-PV cross-correlation, or for an integrating loop Horch
    (2000) PV curvature (:mod:`._horch`), on regular cycles only (Thornhill's regularity
    > 1): on a loop wandering under random loads the cross-correlation's lobes are as
    likely odd as even.
``ellipse``
    Choudhury et al. (2006) OP-PV pattern of the band-passed cycle (:mod:`._ellipse`):
    a thin ellipse (PV follows OP) says not stiction; it also sizes the apparent band.
``kano``
    Kano et al. (2004) stuck intervals: PV still while OP ramps, then a slip
    (:mod:`._kano`).
``stick_slip``
    Stick-slip episodes without a cycle (:mod:`._stickslip`): +1 from ``MIN_EPISODES``
    episodes with one gain sign; never -1.
``hammerstein``
    The He-Wang valve in a Hammerstein fit against a linear valve: does a sticky valve
    explain PV better, and by how much (:mod:`._hammerstein`).
``fast_cycle``
    A cycle too fast for its shape (under 8 samples a period): a sustained limit cycle in
    OP and PV with PV lagging OP, or following it (:mod:`._fastcycle`).

The cycle. Set-point and load steps inside a window hide a limit cycle from the ACF (the
straight-line detrend leaves a step, which dominates it), so each signal is also looked at
with a running median over a third of the window removed (:func:`._oscillation.baseline`),
and the variant with the more significant ACF lobe is kept. A cycle counts when its ACF
lobe is significant and its regularity exceeds ``MIN_REGULARITY``, looser than Thornhill's
1 (which ``Assessment.oscillating`` keeps): stick-slip cycles under load are irregular, and
every shape test has its own guard against noise.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._assessment import Evidence
from ._bicoherence import bicoherence_test
from ._detect import NO_STICTION_SI, STICTION_SI, noise_sd, stiction_index
from ._ellipse import EllipseFit, ellipse_band
from ._fastcycle import fast_cycle
from ._hammerstein import HammersteinFit, hammerstein_test
from ._horch import horch_test
from ._kano import Kano, kano_test
from ._oscillation import MIN_PERIOD, Oscillation, baseline, detect_oscillations, detrend
from ._stickslip import StickSlip, stick_slip
from ._validate import FloatArray

__all__ = ["MIN_CYCLES", "TESTS", "Cycle", "Findings", "find_cycle", "gather",
           "gather_for_calibration"]

TESTS = ("si_op", "si_pv", "bicoherence", "horch", "ellipse", "kano", "stick_slip",
         "hammerstein", "fast_cycle")
MIN_REGULARITY = 0.5
MIN_EPISODES = 2
"""Stick-slip episodes (with one gain sign) a window needs before the test votes: one
episode alone made two of three false calls on outside loops (a fan without a valve, a loop
moved by a disturbance)."""
MIN_CYCLES = 2.5
"""Fewer periods than this in the window: too short to size a limit cycle from."""
SHAPE_CYCLES = 5.0
"""Periods the stiction index needs before it votes: an SI over fewer than ten half cycles
swings by +-0.1 from window to window on one loop (a sine-like disturbance reads 0.62 on four
cycles of a Tennessee Eastman run), across the 0.6 line."""
BASELINE_FRACTION = 3  # running-median window: a third of the window


@dataclasses.dataclass(frozen=True)
class Signal:
    """One signal as the shape tests see it: ``x`` with its baseline (or line) removed."""

    x: FloatArray
    osc: Oscillation
    significance: float
    unstepped: FloatArray  # baseline and line removed, whichever variant ``x`` is


@dataclasses.dataclass(frozen=True)
class Cycle:
    """The oscillation of a window: ``period`` in samples from ``source`` ("OP"/"PV"),
    None when neither signal cycles. ``op``/``pv`` are the signals as the tests see them."""

    op: Signal
    pv: Signal
    period: float | None
    source: str
    regular: bool  # Thornhill's regularity > 1 on OP or PV: what ``oscillating`` reports

    @property
    def cycling(self) -> bool:
        return self.period is not None


def _unstepped(x: FloatArray) -> FloatArray:
    """``x`` without its running-median baseline and straight line."""
    if x.size < 48:
        return detrend(x)
    return detrend(x - baseline(x, x.size // BASELINE_FRACTION))


def _signals(op: FloatArray, pv: FloatArray) -> tuple[Signal, Signal]:
    """OP and PV as the shape tests see them: of each signal's variants (line removed, or
    baseline and line), the one with the more significant ACF lobe. The ACFs of all
    variants in one batch."""
    unstepped = [_unstepped(x) for x in (op, pv)]
    variants = [[detrend(x), u] if x.size >= 48 else [u]
                for x, u in zip((op, pv), unstepped, strict=True)]
    oscs = iter(detect_oscillations([y for v in variants for y in v],
                                    min_regularity=MIN_REGULARITY))
    out = []
    for ys, u in zip(variants, unstepped, strict=True):
        best: Signal | None = None
        for y in ys:
            osc = next(oscs)
            sig = osc.significance if osc.oscillating else -1.0
            if best is None or sig > best.significance:
                best = Signal(y, osc, sig, u)
        assert best is not None
        out.append(best)
    return out[0], out[1]


def find_cycle(op: FloatArray, pv: FloatArray, *, integrating: bool) -> Cycle:
    """The cycle of a window (module doc); OP's for a self-regulating loop, PV's for an
    integrating one, the other signal's when that one does not cycle."""
    so, sp = _signals(op, pv)
    regular = any(s.osc.oscillating and s.osc.regularity > 1.0 for s in (so, sp))
    order = [("PV", sp), ("OP", so)] if integrating else [("OP", so), ("PV", sp)]
    for name, s in order:
        if s.osc.oscillating and s.osc.period is not None:
            return Cycle(so, sp, s.osc.period, name, regular)
    return Cycle(so, sp, None, "", False)


def _si(name: str, s: Signal, fallback: float | None) -> Evidence:
    label = name[-2:].upper()
    period = s.osc.period if s.osc.oscillating else fallback
    if period is None:
        return Evidence(name, None, 0, f"{label} does not cycle")
    if period < MIN_PERIOD:
        return Evidence(name, None, 0, f"{label} cycles too fast to see its shape "
                        f"({period:.1f} samples a period, need {MIN_PERIOD:g})")
    if s.x.size / period < MIN_CYCLES:
        return Evidence(name, None, 0, f"{label}: {s.x.size / period:.1f} cycles, too few "
                        f"to judge the shape (need {SHAPE_CYCLES:g})")
    si = stiction_index(s.x, period)
    if si.si is None:
        return Evidence(name, None, 0, f"too few clean half periods in {label} to fit")
    if not si.resolved:
        return Evidence(name, si.si, 0, f"{label} too noisy to tell a triangle from a sine")
    cycles = s.x.size / period
    if cycles < SHAPE_CYCLES:
        return Evidence(name, si.si, 0, f"{label}: SI {si.si:.2f} over {cycles:.1f} cycles, "
                        f"too few to vote (need {SHAPE_CYCLES:g})")
    if si.si >= STICTION_SI:
        return Evidence(name, si.si, 1, f"{label} half cycles fit a triangle")
    if si.si <= NO_STICTION_SI:
        return Evidence(name, si.si, -1, f"{label} half cycles fit a sine")
    return Evidence(name, si.si, 0, f"{label} neither triangular nor sinusoidal")


def _stick_slip(ss: StickSlip) -> Evidence:
    if ss.detected and len(ss.episodes) < MIN_EPISODES:
        e = ss.episodes[0]
        return Evidence("stick_slip", 1.0, 0, f"one stick-slip episode (OP ramped "
                        f"{e.op_travel:+.3g} with PV still, then PV jumped {e.jump:+.3g}): a "
                        "hint, not evidence alone (a load step can do the same once)")
    if not ss.detected:
        note = ("stick-slip episodes with opposite gain signs" if ss.episodes
                else "no stick-slip episode")
        return Evidence("stick_slip", float(len(ss.episodes)), 0, note)
    e = max(ss.episodes, key=lambda ep: abs(ep.jump))
    count = len(ss.episodes)
    return Evidence("stick_slip", float(count), 1,
                    f"{count} stick-slip episode{'s' if count > 1 else ''}: OP ramped "
                    f"(largest {e.op_travel:+.3g} over {e.stuck} samples) with PV still, "
                    f"then PV jumped ({e.jump:+.3g}) and OP did not")


@dataclasses.dataclass(frozen=True)
class Findings:
    """Every test's evidence (:data:`TESTS` order) and the results that carry a size."""

    evidence: tuple[Evidence, ...]
    ellipse: EllipseFit | None
    kano: Kano
    hammerstein: HammersteinFit
    stick_slip: StickSlip
    noise: tuple[float, float]  # white-noise SDs of OP and PV (noise_sd), for the sizing too

    def vote(self, test: str) -> int:
        return next(e.vote for e in self.evidence if e.test == test)


def gather(op: FloatArray, pv: FloatArray, cycle: Cycle, *, integrating: bool, ts: float
           ) -> Findings:
    """Every test of :data:`TESTS` on a clean window (equal-length, finite)."""
    p = cycle.period
    horch_period = p if p is not None and p >= 1.0 else None
    no_cycle = "no cycle to look at"
    ell = (ellipse_band(cycle.op.x, cycle.pv.x, period=horch_period, integrating=integrating)
           if horch_period is not None else None)
    noise = (noise_sd(op), noise_sd(pv))  # once for the tests that need them
    kano = kano_test(op, pv, period=horch_period, noise=noise)
    ham = hammerstein_test(op, pv, ts=ts, period=horch_period, integrating=integrating)
    ss = stick_slip(op, pv, noise=noise)
    found = {
        "ellipse": ell.evidence() if ell is not None else Evidence("ellipse", None, 0, no_cycle),
        "kano": kano.evidence(),
        "hammerstein": ham.evidence(),
        "fast_cycle": fast_cycle(cycle.op.unstepped, cycle.pv.unstepped).evidence(),
        "si_op": _si("si_op", cycle.op, p),
        "si_pv": _si("si_pv", cycle.pv, p),
        "bicoherence": (bicoherence_test(cycle.pv.x, period=horch_period).evidence()
                        if horch_period is not None
                        else Evidence("bicoherence", None, 0, no_cycle)),
        "horch": (horch_test(cycle.op.x, cycle.pv.x, period=horch_period,
                             integrating=integrating).evidence() if cycle.regular
                  else Evidence("horch", None, 0, "no regular cycle to correlate")),
        "stick_slip": _stick_slip(ss),
    }
    return Findings(tuple(found[name] for name in TESTS), ell, kano, ham, ss, noise)


def gather_for_calibration(op: np.ndarray, pv: np.ndarray, *, ts: float,
                           integrating: bool = False) -> list[int]:
    """The votes of :data:`TESTS` on a raw window as :func:`stiction.analyze` would see it
    (all zero when the window is bad data or a valve not responding)."""
    from ._quality import check_quality  # noqa: PLC0415  (bench-only entry point)

    q = check_quality(np.asarray(op, dtype=np.float64), np.asarray(pv, dtype=np.float64))
    if q.reason is not None or q.not_responding is not None:
        return [0] * len(TESTS)
    cycle = find_cycle(q.op, q.pv, integrating=integrating)
    return [e.vote for e in gather(q.op, q.pv, cycle, integrating=integrating, ts=ts).evidence]
