"""Closed loops with what real loops carry, for calibrating and testing the diagnosis.

The paper's scenarios (:mod:`stiction.scenarios`) are clean: one setpoint step, white noise,
1 s sampling, OP in % of span. Plant records differ in every one of those, and a rule that
only holds on clean simulations is a defect. :func:`realistic_loops` draws loops, each with
a known cause of its behaviour, that carry:

- loads: coloured (first-order filtered) noise, a bounded random walk and load steps, at the
  process input, on every loop;
- setpoint changes (up to three steps) in half of the records;
- white PV noise; PV quantised in a third of the records, OP in a sixth (a 12-bit or 0.1 %
  output card);
- historian sampling every 1-60 s, instantaneous or averaged over the interval;
- OP and PV in other units, with offsets and reverse action (0-1, 4-20 mA, raw counts, ...);
- records of 300 to 10,000 samples; self-regulating (70 %) and integrating (30 %) processes
  with dynamics from a few to a hundred samples.

Causes (``CAUSES``), the answer a plant engineer wants:

``stiction``
    a sticky valve (He, Choudhury or Kano model; static band 1-8 % of span) in a loop tuned
    by the SIMC rules, under loads below its stiction band: the valve that a plant engineer
    finds cycling and labels sticky. The record is stretched to hold at least
    ``MIN_CYCLES`` of its stick-slip cycles (estimated from the simulated valve's slips,
    which must number at least ``MIN_SLIPS``); a sticky valve that never slipped, or
    whose cycle is too slow for 10,000 samples, leaves nothing to find and is not kept.
``tuning``
    a perfect valve in a loop tuned at 60-90 % of its ultimate gain (or with a far too short
    integral time), rung by the loads: a lightly damped, sinusoidal oscillation.
``disturbance``
    a perfect valve and an external periodic load of 1-5 % of span: a sine, two tones, or a
    square wave (on/off) through a lag of 5-30 % of its period, as a load arrives through
    process dynamics.
``propagated``
    a perfect valve whose load is the oscillation of another loop with a sticky valve
    (its PV, through a first-order lag of 5-100 % of that cycle's period: the path through
    headers, vessels and exchangers filters it, so the further from its source the more
    sinusoidal an oscillation, Thornhill et al. 2003): the stiction limit cycle arrives
    from elsewhere.
``noise``
    a perfect valve with loads, setpoint changes and noise, nothing periodic.
``ramp-load``
    a perfect valve and a load that ramps and turns sharply (triangle or sawtooth, 1-5 % of
    span). The loop answers it exactly as it answers a sticky valve: OP ramps against the
    load while PV sits at a constant offset, and flips when the load turns, so OP and PV
    alone cannot tell the two apart. Kept as a cause of its own so that this limit is
    measured, not hidden.

Everything is drawn from ``numpy.random.default_rng((seed, cause, i))``, so a record is
reproducible from its ``(seed, cause, index)`` and records of one cause do not change when
another cause's count does.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import signal

from ._errors import ParameterError
from ._validate import FloatArray
from .simulate import LoopBank, LoopParams
from .valves import ChoudhuryValve, HeValve, KanoValve, ValveModel

__all__ = ["CAUSES", "MIN_SLIPS", "LoopRecord", "realistic_loops"]

CAUSES = ("stiction", "tuning", "disturbance", "propagated", "noise", "ramp-load")
MIN_SLIPS = 6
"""A record of the ``stiction`` cause is kept only when the valve slipped this often in it."""
MIN_CYCLES = 3.0
"""... and when it holds this many stick-slip cycles (two slips a cycle)."""
MAX_SAMPLES = 10_000

OVERSAMPLE = 4  # simulation steps per historian sample
SAMPLE_TIMES = (1.0, 1.0, 2.0, 5.0, 10.0, 10.0, 30.0, 60.0)
OP_UNITS: tuple[tuple[float, float, str], ...] = (
    (1.0, 0.0, "% of span"),
    (1.0, 0.0, "% of span"),
    (0.01, 0.0, "0-1"),
    (0.16, 4.0, "mA"),
    (163.83, 0.0, "counts 0-16383"),
    (-1.0, 100.0, "% reverse acting"),
    (2.5, 300.0, "engineering units with offset"),
    (1.0, -50.0, "% with offset -50"),
)
WAVEFORMS = ("sine", "square", "two-tone")
RAMP_WAVEFORMS = ("triangle", "sawtooth")


@dataclasses.dataclass(frozen=True)
class LoopRecord:
    """One record: OP and PV in their own units, sampled every ``ts`` seconds.

    ``op_range`` is the pair of OP values at 0 % and 100 % valve span (lo < hi) and ``fs``,
    ``fd`` are the valve's static and dynamic friction as fractions of span (0 for a good
    valve; for the two-parameter models the static band S and the slip J map to fs = S/2 +
    J/2 and fd = S/2 - J/2, the He-model equivalents).
    """

    cause: str
    index: int
    ts: float
    process: str
    op: FloatArray
    pv: FloatArray
    op_range: tuple[float, float]
    fs: float
    fd: float
    description: str
    vp: FloatArray  # the valve position, fraction of span, sampled as OP (not measured)

    @property
    def sticky(self) -> bool:
        return self.cause == "stiction"


@dataclasses.dataclass
class _Draw:
    """Everything drawn for one record before simulation (fractions of span, seconds)."""

    cause: str
    index: int
    rng: np.random.Generator
    ts: float
    n: int
    integrating: bool
    kp: float
    tau: float
    theta: float
    kc: float = 0.0
    ti: float = 0.0
    x0: float = 0.5
    noise: float = 0.1
    valve: str = "perfect"
    s: float = 0.0
    j: float = 0.0
    notes: list[str] = dataclasses.field(default_factory=list)

    @property
    def ts_sim(self) -> float:
        return self.ts / OVERSAMPLE

    @property
    def n_sim(self) -> int:
        """Simulation steps: a sticky loop runs long enough for the longest record, which
        is cut to hold ``MIN_CYCLES`` of its cycle once the cycle is known."""
        n = MAX_SAMPLES if self.cause == "stiction" else self.n
        return OVERSAMPLE * (n + self.warm)

    @property
    def warm(self) -> int:
        return 500


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _ultimate_gain(d: _Draw) -> float:
    """Gain at which the PI loop (integral time ``d.ti``) reaches -180 degrees of phase:
    the process with its dead time plus 1.5 simulation steps (hold and computation)."""
    theta = d.theta + 1.5 * d.ts_sim
    w = np.geomspace(1e-6, math.pi / d.ts_sim, 4000)
    pi_phase = -np.arctan(1.0 / (d.ti * w))
    if d.integrating:
        phase = -math.pi / 2 - theta * w + pi_phase
        mag = d.kp / w
    else:
        phase = -theta * w - np.arctan(d.tau * w) + pi_phase
        mag = d.kp / np.sqrt(1.0 + (d.tau * w) ** 2)
    mag = mag * np.sqrt(1.0 + 1.0 / (d.ti * w) ** 2)
    k = np.flatnonzero(phase <= -math.pi)
    if k.size == 0:
        return float("inf")
    return float(1.0 / mag[k[0]])


def _draw(cause: str, index: int, seed: int) -> _Draw:
    rng = np.random.default_rng((seed, CAUSES.index(cause), index))
    ts = float(rng.choice(SAMPLE_TIMES))
    n = int(_loguniform(rng, 300, 10_000))
    integrating = bool(rng.random() < 0.3)
    # dynamics in historian samples: from a few to about a hundred
    if integrating:
        horizon = ts * _loguniform(rng, 4.0, 60.0)  # closed-loop time scale
        kp, tau, theta = 1.0 / horizon, 1.0, horizon * rng.uniform(0.0, 0.2)
    else:
        tau = ts * _loguniform(rng, 1.5, 60.0)
        kp, theta = _loguniform(rng, 0.3, 3.0), tau * rng.uniform(0.0, 0.5)
    d = _Draw(cause, index, rng, ts, n, integrating, kp, tau, theta)
    # SIMC tuning (Skogestad 2003), with lambda drawn between tight and relaxed
    if integrating:
        lam = horizon * rng.uniform(0.3, 1.0)
        d.kc, d.ti = 1.0 / (kp * (lam + theta + d.ts_sim)), 4.0 * (lam + theta + d.ts_sim)
    else:
        lam = max(theta, tau * rng.uniform(0.2, 1.0))
        d.kc = tau / (kp * (lam + theta + d.ts_sim))
        d.ti = min(tau, 4.0 * (lam + theta + d.ts_sim))
    d.x0 = rng.uniform(0.25, 0.75)
    d.noise = _loguniform(rng, 0.02, 0.5)
    if cause == "tuning":
        if rng.random() < 0.7:
            d.kc = _ultimate_gain(d) * rng.uniform(0.6, 0.9)
            d.notes.append("gain at 60-90 % of ultimate")
        else:
            d.ti = d.ti * rng.uniform(0.03, 0.12)
            d.kc = min(d.kc, 0.9 * _ultimate_gain(d))
            d.notes.append("integral time far too short")
        if not math.isfinite(d.kc):
            d.kc = 10.0 / kp
    elif cause == "stiction":
        d.valve = str(rng.choice(("he", "he", "choudhury", "kano")))
        fs = _loguniform(rng, 0.01, 0.08)
        fd = fs * rng.uniform(0.4, 0.9)
        d.s, d.j = fs + fd, fs - fd  # He (fs, fd) -> band S and slip J
        # PV noise through the controller gain moves OP by at most a third of fs
        d.noise = min(d.noise, rng.uniform(0.05, 0.3) * fs * 100.0 / d.kc)
        d.notes.append(f"{d.valve} valve fs {fs:.3f} fd {fd:.3f}")
    return d


def _filtered(rng: np.random.Generator, n: int, tau_samples: float) -> FloatArray:
    """Unit-SD white noise through a first-order filter of ``tau_samples``."""
    c = math.exp(-1.0 / max(tau_samples, 1e-3))
    w = rng.standard_normal(n) * math.sqrt(1.0 - c * c)
    return np.asarray(signal.lfilter([1.0], [1.0, -c], w), dtype=np.float64)


def _loads(d: _Draw) -> FloatArray:
    """Load at the process input, fraction of span, one value per simulation step: coloured
    noise, a bounded random walk and steps, each of a few percent of span. A sticky valve's
    loop gets them scaled to its static friction instead (coloured SD 5-30 % of fs, walk
    and steps up to 1.5 fs): a loop whose loads swamp the stiction shows no stiction
    pattern to label it by, and is not what a plant engineer calls a sticky valve."""
    rng, n = d.rng, d.n_sim
    cl = (d.ti if not d.integrating else d.ti / 2.0) / d.ts_sim  # closed-loop scale, steps
    sticky = d.cause == "stiction"
    unit = 0.5 * (d.s + d.j) if sticky else 0.01
    sd = unit * (rng.uniform(0.05, 0.3) if sticky else rng.uniform(0.1, 1.5))
    load = sd * _filtered(rng, n, cl * _loguniform(rng, 0.3, 10.0))
    walk = np.cumsum(rng.standard_normal(n))
    walk = signal.detrend(walk) if rng.random() < 0.5 else walk - walk[0]
    big = 1.5 if sticky else 3.0
    load += unit * rng.uniform(0.0, big) * walk / max(float(np.ptp(walk)), 1e-12)
    for _ in range(rng.poisson(0.7)):
        load[rng.integers(0, n) :] += unit * rng.uniform(-big, big)
    return load


def _periodic(d: _Draw, kind: str) -> FloatArray:
    rng, n = d.rng, d.n_sim
    period = d.ts * _loguniform(rng, 8.0, 150.0) / d.ts_sim  # steps
    ph = np.arange(n) / period + rng.uniform(0, 1)
    frac = ph % 1.0
    if kind == "sine":
        x = np.sin(2 * np.pi * ph)
    elif kind == "square":
        c = math.exp(-1.0 / (period * rng.uniform(0.05, 0.3)))
        x = signal.lfilter([1.0 - c], [1.0, -c], np.sign(np.sin(2 * np.pi * ph)))
    elif kind == "triangle":
        x = 4.0 * np.abs(frac - 0.5) - 1.0
    elif kind == "sawtooth":
        x = 2.0 * frac - 1.0
    else:
        x = np.sin(2 * np.pi * ph) + 0.6 * np.sin(2 * np.pi * ph * rng.uniform(2.2, 3.7) + 1.0)
    x = np.asarray(x, dtype=np.float64)
    return 0.01 * rng.uniform(1.0, 5.0) * x / max(float(np.std(x)) * math.sqrt(2.0), 1e-12)


def _setpoints(d: _Draw) -> FloatArray:
    sp = np.zeros(d.n_sim)
    if d.rng.random() < 0.5:
        for _ in range(int(d.rng.integers(1, 4))):
            sp[d.rng.integers(0, d.n_sim) :] += d.rng.uniform(-5.0, 5.0)
    return sp


def _valve(kind: str, draws: Sequence[_Draw]) -> ValveModel[Any]:
    s = np.array([x.s for x in draws])
    j = np.array([x.j for x in draws])
    if kind == "choudhury":
        return ChoudhuryValve(s, j)
    if kind == "kano":
        return KanoValve(s, j)
    if kind == "he":
        return HeValve((s + j) / 2.0, (s - j) / 2.0, 1.99)
    return HeValve(np.zeros(len(draws)), np.zeros(len(draws)), 1.0)


def _simulate(draws: Sequence[_Draw], loads: FloatArray, seed: int
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """OP (fraction), PV (%-like units) and VP (fraction) of loops sharing a step and valve
    model, as (loops, steps) arrays."""
    params = LoopParams(
        kc=[x.kc for x in draws], ti=[x.ti for x in draws], kp=[x.kp for x in draws],
        tau=[x.tau for x in draws], theta=[x.theta for x in draws],
        integrating=[x.integrating for x in draws], x0=[x.x0 for x in draws],
        noise_sd=[x.noise for x in draws])
    d0 = draws[0]
    bank = LoopBank(len(draws), params, _valve(d0.valve, draws), ts=d0.ts_sim, seed=seed)
    n = max(x.n_sim for x in draws)
    sp = np.zeros((len(draws), n))
    for i, x in enumerate(draws):
        sp[i, : x.n_sim] = _setpoints(x)
    sp += 50.0
    out = np.empty((3, len(draws), n))
    for k in range(n):
        s = bank.step(sp[:, k], loads[:, k])
        out[0, :, k], out[1, :, k], out[2, :, k] = s.op / 100.0, s.pv, s.vp / 100.0
    return out[0], out[1], out[2]


def _slips(vp: FloatArray) -> FloatArray:
    """Steps at which the valve broke away: moves that follow at least two steps at rest."""
    moving = np.abs(np.diff(vp)) > 1e-9
    if moving.size < 3:
        return np.empty(0)
    start = moving[2:] & ~moving[1:-1] & ~moving[:-2]
    return np.flatnonzero(start).astype(np.float64)


def _length(d: _Draw, vp: FloatArray) -> int:
    """Samples in the record: the drawn length, for a sticky valve stretched to hold
    ``MIN_CYCLES`` of its stick-slip cycle (0 when the valve hardly slips or cycles too
    slowly for ``MAX_SAMPLES``)."""
    if d.cause != "stiction":
        return d.n
    slips = _slips(vp[OVERSAMPLE * d.warm :])
    if slips.size < MIN_SLIPS:
        return 0
    period = 2.0 * float(np.median(np.diff(slips))) / OVERSAMPLE
    n = max(d.n, math.ceil(MIN_CYCLES * period))
    if n > MAX_SAMPLES or np.count_nonzero(slips < OVERSAMPLE * n) < MIN_SLIPS:
        return 0
    return n


def _record(d: _Draw, op: FloatArray, pv: FloatArray, vp: FloatArray) -> LoopRecord | None:
    rng = d.rng
    n = _length(d, vp)
    if n == 0:
        return None
    d.n = n
    sl = slice(OVERSAMPLE * d.warm, OVERSAMPLE * (d.warm + n))
    op, pv, vp = op[sl], pv[sl], vp[sl]
    if rng.random() < 0.3:  # historian averages over the interval
        op = op.reshape(-1, OVERSAMPLE).mean(axis=1)
        pv = pv.reshape(-1, OVERSAMPLE).mean(axis=1)
        vp = vp.reshape(-1, OVERSAMPLE).mean(axis=1)
        d.notes.append("averaged samples")
    else:
        op, pv = op[OVERSAMPLE - 1 :: OVERSAMPLE], pv[OVERSAMPLE - 1 :: OVERSAMPLE]
        vp = vp[OVERSAMPLE - 1 :: OVERSAMPLE]
    if rng.random() < 1 / 6:
        op = np.round(op * 1000.0) / 1000.0 if rng.random() < 0.5 else np.round(op * 4095) / 4095
        d.notes.append("OP quantised")
    if rng.random() < 1 / 3:
        p5, p95 = np.percentile(pv, [5, 95])
        q = max(float(p95 - p5), 1e-6) / _loguniform(rng, 15.0, 150.0)
        pv = np.round(pv / q) * q
        d.notes.append("PV quantised")
    a, b, unit = OP_UNITS[int(rng.integers(0, len(OP_UNITS)))]
    op = a * 100.0 * op + b
    lo, hi = sorted((b, 100.0 * a + b))
    c, off = _loguniform(rng, 0.01, 50.0), rng.uniform(-500.0, 500.0)
    pv = c * pv + off
    fs, fd = (d.s + d.j) / 2.0, (d.s - d.j) / 2.0
    desc = (f"{d.cause} #{d.index}: {'integrating' if d.integrating else 'self-regulating'}, "
            f"ts {d.ts:g} s, {d.n} samples, OP in {unit}; " + ", ".join(d.notes))
    return LoopRecord(d.cause, d.index, d.ts, "integrating" if d.integrating else
                      "self-regulating", np.ascontiguousarray(op), np.ascontiguousarray(pv),
                      (lo, hi), fs, fd, desc, np.ascontiguousarray(vp))


def _upstream(draws: Sequence[_Draw], seed: int) -> list[FloatArray]:
    """The oscillation a sticky loop elsewhere sends into each of ``draws`` (all with one
    sample time), in simulation steps of the receiving loop."""
    ups = []
    for d in draws:
        rng = d.rng
        up = _Draw("upstream", d.index, rng, d.ts, d.n, False, 1.0,
                   d.ts * _loguniform(rng, 2.0, 30.0), 0.0)
        up.theta = up.tau * rng.uniform(0.0, 0.3)
        up.kc, up.ti = up.tau / (up.kp * (up.tau * 0.5 + up.theta + up.ts_sim)), up.tau
        up.valve = "he"
        fs = _loguniform(rng, 0.02, 0.08)
        up.s, up.j = fs * 1.8, fs * 0.2
        d.notes.append(f"load from a sticky loop upstream (fs {fs:.3f})")
        ups.append(up)
    n = max(u.n_sim for u in ups)
    loads = np.stack([0.003 * _filtered(u.rng, n, 50.0) for u in ups])
    _, pv, vp = _simulate(ups, loads, seed + 7919)
    out = []
    for d, u, y, v in zip(draws, ups, pv, vp, strict=True):
        x = y[: u.n_sim] - y[: u.n_sim].mean()
        slips = _slips(v[: u.n_sim])
        period = 2.0 * float(np.median(np.diff(slips))) if slips.size > 2 else 50.0
        # the path from the sticky loop (pipes, vessels, exchangers) filters its cycle:
        # a lag of 5 % (a shared header) to 100 % (a vessel) of the cycle's period
        c = math.exp(-1.0 / (period * _loguniform(d.rng, 0.05, 1.0)))
        x = signal.lfilter([1.0 - c], [1.0, -c], x)
        amp = 0.01 * d.rng.uniform(1.0, 5.0) / max(float(np.std(x)) * math.sqrt(2.0), 1e-12)
        out.append(np.asarray(amp * x, dtype=np.float64))
    return out


def realistic_loops(cause: str, count: int, *, seed: int = 0) -> list[LoopRecord]:
    """``count`` records of ``cause`` (one of :data:`CAUSES`), reproducible from ``seed``.

    For ``stiction`` only records in which the valve slipped at least :data:`MIN_SLIPS`
    times and which hold :data:`MIN_CYCLES` of its cycle are returned; candidates are drawn
    until ``count`` are found.
    """
    if cause not in CAUSES:
        raise ParameterError("cause", f"must be one of {', '.join(CAUSES)}; was {cause!r}")
    if isinstance(count, bool) or int(count) != count or count < 0:
        raise ParameterError("count", f"must be a non-negative integer, was {count!r}")
    out: list[LoopRecord] = []
    index = 0
    while len(out) < count and index < 20 * count + 20:
        batch = [_draw(cause, index + i, seed) for i in range(max(count - len(out), 1) * 2)]
        index += len(batch)
        for rec in sorted(_run(batch, seed), key=lambda r: r.index):
            if len(out) < count:
                out.append(rec)
    return out


def _run(draws: list[_Draw], seed: int) -> list[LoopRecord]:
    groups: dict[tuple[float, str], list[_Draw]] = {}
    for d in draws:
        groups.setdefault((d.ts, d.valve), []).append(d)
    recs: list[LoopRecord] = []
    for (_, _valve_kind), group in sorted(groups.items()):
        n = max(x.n_sim for x in group)
        loads = np.zeros((len(group), n))
        prop = [d for d in group if d.cause == "propagated"]
        upstream = dict(zip((d.index for d in prop), _upstream(prop, seed), strict=True)) \
            if prop else {}
        for i, d in enumerate(group):
            load = _loads(d)
            if d.cause in ("disturbance", "ramp-load"):
                kind = str(d.rng.choice(WAVEFORMS if d.cause == "disturbance"
                                        else RAMP_WAVEFORMS))
                load = load + _periodic(d, kind)
                d.notes.append(f"{kind} load")
            elif d.cause == "propagated":
                load = load + upstream[d.index]
            loads[i, : d.n_sim] = load
        op, pv, vp = _simulate(group, loads, seed + group[0].index)
        for i, d in enumerate(group):
            rec = _record(d, op[i, : d.n_sim], pv[i, : d.n_sim], vp[i, : d.n_sim])
            if rec is not None:
                recs.append(rec)
    return recs
