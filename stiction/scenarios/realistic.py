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

from .._errors import ParameterError
from .._validate import FloatArray
from ..models.simulate import LoopBank, LoopParams
from ..models.valves import ChoudhuryValve, HeValve, KanoValve, ValveModel
from .draws import (
    CAUSES,
    MAX_SAMPLES,
    OP_UNITS,
    OVERSAMPLE,
    RAMP_WAVEFORMS,
    WAVEFORMS,
    Draw,
    draw,
    filtered_noise,
    load_signal,
    loguniform,
    periodic_load,
    setpoint_steps,
)

__all__ = ["CAUSES", "MIN_SLIPS", "LoopRecord", "realistic_loops"]

MIN_SLIPS = 6
"""A record of the ``stiction`` cause is kept only when the valve slipped this often in it."""
MIN_CYCLES = 3.0
"""... and when it holds this many stick-slip cycles (two slips a cycle)."""


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


def _valve(kind: str, draws: Sequence[Draw]) -> ValveModel[Any]:
    s = np.array([x.s for x in draws])
    j = np.array([x.j for x in draws])
    if kind == "choudhury":
        return ChoudhuryValve(s, j)
    if kind == "kano":
        return KanoValve(s, j)
    if kind == "he":
        return HeValve((s + j) / 2.0, (s - j) / 2.0, 1.99)
    return HeValve(np.zeros(len(draws)), np.zeros(len(draws)), 1.0)


def _simulate(draws: Sequence[Draw], loads: FloatArray, seed: int
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
        sp[i, : x.n_sim] = setpoint_steps(x)
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


def _length(d: Draw, vp: FloatArray) -> int:
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


def _record(d: Draw, op: FloatArray, pv: FloatArray, vp: FloatArray) -> LoopRecord | None:
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
        q = max(float(p95 - p5), 1e-6) / loguniform(rng, 15.0, 150.0)
        pv = np.round(pv / q) * q
        d.notes.append("PV quantised")
    a, b, unit = OP_UNITS[int(rng.integers(0, len(OP_UNITS)))]
    op = a * 100.0 * op + b
    lo, hi = sorted((b, 100.0 * a + b))
    c, off = loguniform(rng, 0.01, 50.0), rng.uniform(-500.0, 500.0)
    pv = c * pv + off
    fs, fd = (d.s + d.j) / 2.0, (d.s - d.j) / 2.0
    desc = (f"{d.cause} #{d.index}: {'integrating' if d.integrating else 'self-regulating'}, "
            f"ts {d.ts:g} s, {d.n} samples, OP in {unit}; " + ", ".join(d.notes))
    return LoopRecord(d.cause, d.index, d.ts, "integrating" if d.integrating else
                      "self-regulating", np.ascontiguousarray(op), np.ascontiguousarray(pv),
                      (lo, hi), fs, fd, desc, np.ascontiguousarray(vp))


def _upstream(draws: Sequence[Draw], seed: int) -> list[FloatArray]:
    """The oscillation a sticky loop elsewhere sends into each of ``draws`` (all with one
    sample time), in simulation steps of the receiving loop."""
    ups = []
    for d in draws:
        rng = d.rng
        up = Draw("upstream", d.index, rng, d.ts, d.n, False, 1.0,
                   d.ts * loguniform(rng, 2.0, 30.0), 0.0)
        up.theta = up.tau * rng.uniform(0.0, 0.3)
        up.kc, up.ti = up.tau / (up.kp * (up.tau * 0.5 + up.theta + up.ts_sim)), up.tau
        up.valve = "he"
        fs = loguniform(rng, 0.02, 0.08)
        up.s, up.j = fs * 1.8, fs * 0.2
        d.notes.append(f"load from a sticky loop upstream (fs {fs:.3f})")
        ups.append(up)
    n = max(u.n_sim for u in ups)
    loads = np.stack([0.003 * filtered_noise(u.rng, n, 50.0) for u in ups])
    _, pv, vp = _simulate(ups, loads, seed + 7919)
    out = []
    for d, u, y, v in zip(draws, ups, pv, vp, strict=True):
        x = y[: u.n_sim] - y[: u.n_sim].mean()
        slips = _slips(v[: u.n_sim])
        period = 2.0 * float(np.median(np.diff(slips))) if slips.size > 2 else 50.0
        # the path from the sticky loop (pipes, vessels, exchangers) filters its cycle:
        # a lag of 5 % (a shared header) to 100 % (a vessel) of the cycle's period
        c = math.exp(-1.0 / (period * loguniform(d.rng, 0.05, 1.0)))
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
        batch = [draw(cause, index + i, seed) for i in range(max(count - len(out), 1) * 2)]
        index += len(batch)
        for rec in sorted(_run(batch, seed), key=lambda r: r.index):
            if len(out) < count:
                out.append(rec)
    return out


def _run(draws: list[Draw], seed: int) -> list[LoopRecord]:
    groups: dict[tuple[float, str], list[Draw]] = {}
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
            load = load_signal(d)
            if d.cause in ("disturbance", "ramp-load"):
                kind = str(d.rng.choice(WAVEFORMS if d.cause == "disturbance"
                                        else RAMP_WAVEFORMS))
                load = load + periodic_load(d, kind)
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
