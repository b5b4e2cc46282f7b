"""One chunk of the shape corpus: ``PAIRS`` loops drawn from a seed (lab/shape/draws.py),
each run twice in one :class:`~stiction.models.simulate.LoopBank`: with its sticky valve and
with a linear valve (the **twin**), the same process, tuning, loads, noise and setpoints, then
both through the same historian. The twin is always a negative (whatever cycles it shows
comes from its loads or its tuning); the sticky run is labelled by how much its valve
changed what the historian shows (:func:`label`).

Measurement noise enters as the setpoint minus the noise (the controller sees SP - (PV +
n), exactly as with noise on PV) and is added to the recorded PV, so a loop and its twin
share it sample for sample without touching the bank's own random draws."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from stiction._validate import FloatArray
from stiction.models.simulate import LoopBank, LoopParams
from stiction.models.valves import ChoudhuryValve, HeValve, KanoValve, ValveModel

from . import historian, loads
from .draws import STEPS, WARM, Loop, draw, loguniform
from .valves import LaggedValve, MixedValve

PAIRS = 96
UPSTREAM = 8
UPSTREAM_STEPS = 8_000
MIN_SLIPS = 2  # one stick-slip cycle in the window (real records hold one or two)
VISIBLE = 0.5  # var(sticky - twin) / var(twin's error): at least this for a positive
INVISIBLE = 0.1  # below this on PV and OP the sticky run is its twin's copy: dropped


@dataclasses.dataclass(frozen=True)
class Example:
    """One window of the corpus: ``y`` 1 for stiction that visibly shaped the loop, 0 for a
    linear valve; ``pair`` is shared by a sticky run and its twin."""

    op: np.ndarray  # float32, % of span
    pv: np.ndarray  # float32, PV units
    y: int
    pair: int
    kind: str  # "stiction", or the twin's cause: "periodic", "propagated", "tuning", ...
    meta: dict[str, Any]


def _slips(x: FloatArray) -> int:
    """Break-aways of a valve position: moves after at least two steps at rest."""
    moving = np.abs(np.diff(x)) > 1e-9
    if moving.size < 3:
        return 0
    return int(np.count_nonzero(moving[2:] & ~moving[1:-1] & ~moving[:-2]))


def _friction(loops: list[Loop], n: int) -> MixedValve:
    """The sticky valves (loops 0..n-1) by model, and the twins' linear valves (n..2n-1)."""
    groups: list[tuple[np.ndarray, ValveModel[Any]]] = []
    for kind in sorted({lp.valve for lp in loops}):
        idx = np.array([i for i, lp in enumerate(loops) if lp.valve == kind], dtype=np.intp)
        fs = np.array([loops[i].fs for i in idx])
        fd = np.array([loops[i].fd for i in idx])
        k = np.array([loops[i].k for i in idx])
        model: ValveModel[Any]
        if kind == "choudhury":
            model = ChoudhuryValve(fs + fd, fs - fd)
        elif kind == "kano":
            model = KanoValve(fs + fd, fs - fd)
        else:
            model = HeValve(fs, fd, k)
        groups.append((idx, model))
    groups.append((np.arange(n, 2 * n), HeValve(np.zeros(n), np.zeros(n), np.ones(n))))
    return MixedValve(2 * n, groups)


def _bank(loops: list[Loop], valve: ValveModel[Any]) -> LoopBank:
    two = loops + loops
    params = LoopParams(
        kc=[lp.kc for lp in two], ti=[lp.ti for lp in two], kp=[lp.kp for lp in two],
        tau=[lp.tau for lp in two], theta=[lp.theta for lp in two],
        integrating=[lp.integrating for lp in two], x0=[lp.x0 for lp in two])
    taus = np.array([[lp.lags[0] for lp in two], [lp.lags[1] for lp in two]])
    return LoopBank(len(two), params, LaggedValve(valve, taus), ts=1.0, seed=0)


def upstream(seed: int) -> list[tuple[FloatArray, float]]:
    """PVs of sticky loops elsewhere (unit SD) and their periods in steps."""
    rng = np.random.default_rng((36, seed, 99))
    ups = []
    for j in range(UPSTREAM):
        lp = draw(seed, 100_000 + j)
        lp.integrating, lp.kp = False, loguniform(rng, 0.5, 2.0)
        lp.tau, lp.theta, lp.lags = loguniform(rng, 3.0, 30.0), 0.0, (0.0, 0.0)
        lp.theta = lp.tau * rng.uniform(0.0, 0.3)
        lp.kc = lp.tau / (lp.kp * (0.5 * lp.tau + lp.theta + 1.5))
        lp.ti, lp.valve, lp.k = lp.tau, "he", 1.0
        lp.fs = loguniform(rng, 0.02, 0.08)
        lp.fd = lp.fs * rng.uniform(0.3, 0.9)
        ups.append(lp)
    bank = _bank(ups, _friction(ups, len(ups)))
    pv = np.empty((len(ups), UPSTREAM_STEPS))
    x = np.empty((len(ups), UPSTREAM_STEPS))
    noise = 0.003 * rng.standard_normal((2 * len(ups), UPSTREAM_STEPS))
    for k in range(UPSTREAM_STEPS):
        out = bank.step(load=noise[:, k])
        pv[:, k] = out.pv[: len(ups)]
        x[:, k] = bank.valve_state.inner.x[: len(ups)]
    res = []
    for i in range(len(ups)):
        y = pv[i, 1000:] - pv[i, 1000:].mean()
        moving = np.abs(np.diff(x[i, 1000:])) > 1e-9
        starts = np.flatnonzero(moving[2:] & ~moving[1:-1] & ~moving[:-2])
        period = 2.0 * float(np.median(np.diff(starts))) if starts.size > 2 else 50.0
        res.append((np.asarray(y / max(float(np.std(y)), 1e-12)), period))
    return res


def _propagated(loop: Loop, rng: np.random.Generator, ups: list[tuple[FloatArray, float]],
                n: int) -> FloatArray:
    """An upstream cycle stretched to a period of 0.5-20 times the loop's scale and passed
    through a lag of 5-100 % of that period (a header, a vessel, an exchanger)."""
    y, p_up = ups[int(rng.integers(0, len(ups)))]
    period = loop.scale * loguniform(rng, 0.5, 20.0)
    t = (np.arange(n) * p_up / period + rng.uniform(0, y.size)) % (y.size - 1)
    x = loads.lag(np.interp(t, np.arange(y.size), y), period * loguniform(rng, 0.05, 1.0))
    return np.asarray((x - x.mean()) / max(float(np.std(x)), 1e-12))


def run(seed: int, pairs: int = PAIRS) -> tuple[list[Loop], np.ndarray, np.ndarray,
                                                 np.ndarray, np.ndarray, np.ndarray]:
    """Simulate a chunk: (loops, OP %, PV, SP, noise, valve position) with rows 0..n-1 the
    sticky runs and n..2n-1 their twins; PV holds its measurement noise."""
    loops = [draw(seed, i) for i in range(pairs)]
    n_steps = WARM + STEPS
    ups = upstream(seed)
    ld, nz, sp = (np.empty((pairs, n_steps)) for _ in range(3))
    for i, lp in enumerate(loops):
        rng = np.random.default_rng((36, seed, i, 1))
        prop = _propagated(lp, rng, ups, n_steps) if lp.propagated_amp else None
        ld[i] = loads.load(lp, rng, n_steps, prop)
        nz[i] = loads.noise(lp, rng, n_steps)
        sp[i] = loads.setpoint(lp, rng, n_steps)
    bank = _bank(loops, _friction(loops, pairs))
    ld2, sp2 = np.vstack([ld, ld]), np.vstack([sp - nz, sp - nz])
    op, pv, x = (np.empty((2 * pairs, STEPS), dtype=np.float32) for _ in range(3))
    for k in range(n_steps):
        out = bank.step(sp2[:, k], ld2[:, k])
        if k >= WARM:
            op[:, k - WARM], pv[:, k - WARM] = out.op, out.pv
            x[:, k - WARM] = bank.valve_state.inner.x
    nz2 = np.vstack([nz, nz])[:, WARM:]
    pv += nz2.astype(np.float32)
    return loops, op, pv, np.vstack([sp, sp])[:, WARM:], nz2, x


def ratio(a: FloatArray, b: FloatArray, ref: FloatArray) -> float:
    """var(a - b) / var(ref): how much of the twin's variation the valve changed."""
    return float(np.var(a - b) / max(float(np.var(ref)), 1e-12))


def label(loop: Loop, slips: int, r_pv: float, r_op: float) -> str:
    """``stiction`` (a positive), ``invisible`` or ``ambiguous`` (dropped): a sticky run is a
    positive when its valve stuck and slipped at least ``MIN_SLIPS`` times in the window
    and changed PV by at least ``VISIBLE`` of the twin's error variance; it is dropped as
    its twin's copy when it changed PV and OP by less than ``INVISIBLE`` (the twin stands
    for it as a negative: a second negative would be the same example twice, a positive
    would teach the network to see what is not there), and dropped as ambiguous between."""
    if slips >= MIN_SLIPS and r_pv >= VISIBLE:
        return "stiction"
    if r_pv < INVISIBLE and r_op < INVISIBLE:
        return "invisible"
    return "ambiguous"


def twin_kind(loop: Loop) -> str:
    if loop.propagated_amp:
        return "propagated"
    if loop.periodic:
        return f"periodic-{loop.periodic}"
    if loop.tuning in ("aggressive", "short-ti"):
        return "tuning"
    return "normal"


def chunk(seed: int, pairs: int = PAIRS) -> tuple[list[Example], dict[str, int]]:
    """The windows of one chunk, and how many sticky runs each label took."""
    loops, op, pv, sp, _, x = run(seed, pairs)
    out: list[Example] = []
    tally: dict[str, int] = {}
    for i, lp in enumerate(loops):
        span = lp.samples * lp.interval
        a = int(lp.offset * (STEPS - span))
        w = slice(a, a + span)
        t_op, t_pv = historian.record(lp, op[pairs + i, w], pv[pairs + i, w],
                                      historian.sample(op[pairs + i, w], lp.interval, False),
                                      historian.sample(pv[pairs + i, w], lp.interval, False))
        s_op, s_pv = historian.record(lp, op[i, w], pv[i, w],
                                      historian.sample(op[pairs + i, w], lp.interval, False),
                                      historian.sample(pv[pairs + i, w], lp.interval, False))
        err = t_pv - historian.sample(sp[pairs + i, w], lp.interval, lp.averaged)
        r_pv, r_op = ratio(s_pv, t_pv, err), ratio(s_op, t_op, t_op)
        slips = _slips(x[i, w])
        verdict = label(lp, slips, r_pv, r_op)
        tally[verdict] = tally.get(verdict, 0) + 1
        meta = {"seed": seed, "index": i, "interval": lp.interval, "valve": lp.valve,
                "fs": lp.fs, "fd": lp.fd, "integrating": lp.integrating,
                "tuning": lp.tuning, "r_pv": r_pv, "r_op": r_op, "slips": slips,
                "describe": lp.describe()}
        pair = seed * 1000 + i
        out.append(Example(t_op.astype(np.float32), t_pv.astype(np.float32), 0, pair,
                           twin_kind(lp), meta))
        if verdict == "stiction":
            out.append(Example(s_op.astype(np.float32), s_pv.astype(np.float32), 1, pair,
                               "stiction", meta))
        if not math.isfinite(r_pv):
            raise ValueError(f"loop {seed}/{i} diverged: {lp.describe()}")
    return out, tally
