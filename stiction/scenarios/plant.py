"""A plant of interacting loops: one oscillation born in one place and carried by many.

A :class:`PlantScenario` is a set of PI loops (:class:`PlantLoop`, each a valve, He's model,
and a first-order or integrating process with dead time), the paths between them
(:class:`Link`: one loop's PV through a lag into another's process as a load, or one loop's
OP as another's setpoint, a cascade), periodic loads from outside (:class:`External`, e.g.
a utility header) and measured signals that belong to no loop (:class:`Indicator`).
:func:`simulate_plant` runs one; many plants run at once in one vector (their loops side by
side, each plant's links among its own), so a batch costs about what one plant costs.

Units as in :mod:`stiction.models.simulate`: OP and valve position in % of span, PV in
process units (``pv0 + 100 y``); link gains are fractions of span per fraction of span.

In a cascade (``Link(kind="setpoint")``) the source is the outer loop: its OP, in % of
span, moves the inner loop's setpoint by ``gain`` PV units per % about the inner
operating point, and the outer process is driven by the inner loop's PV (its own valve
takes no part: ``PlantLoop(valve=False)``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .._errors import ParameterError
from .._validate import FloatArray

__all__ = ["SIGNALS", "External", "Indicator", "Link", "PlantLoop", "PlantRecord",
           "PlantScenario", "simulate_plants"]

SIGNALS = ("pv", "process", "valve")
"""What an indicator of a loop reads (:class:`Indicator`)."""


@dataclasses.dataclass(frozen=True)
class PlantLoop:
    """One PI loop: process ``kp exp(-theta s) / (tau s + 1)`` (or ``/ s``), a He valve
    (``fs``, ``fd`` fractions of span; 0 a good valve), white PV noise and a random load."""

    name: str
    kp: float = 1.0
    tau: float = 60.0
    theta: float = 5.0
    integrating: bool = False
    kc: float = 1.0
    ti: float = 60.0
    fs: float = 0.0
    fd: float = 0.0
    k: float = 1.0  # 1 with fs = fd = 0: a perfect valve; 1.99 for He's Table 1 valve
    noise_sd: float = 0.05
    load_sd: float = 0.002  # fraction of span, first-order filtered
    load_tau: float = 120.0
    valve: bool = True  # False: the outer loop of a cascade (its OP is a setpoint)
    sp_step: float = 0.0  # PV units at 60 s (into the warm-up): starts a stick-slip cycle
    sensor_tau: float = 0.0  # s: PV measured through a first-order lag (its transmitter)
    quantum: float = 0.0  # OP and PV written in steps of this (a historian's resolution)

    @property
    def sticky(self) -> bool:
        return self.valve and self.fs > 0


@dataclasses.dataclass(frozen=True)
class Link:
    """``source``'s PV (``kind="load"``) into ``target``'s process through ``gain`` and a
    first-order lag ``tau`` (s) after ``delay`` (s); or ``source``'s OP as ``target``'s
    setpoint (``kind="setpoint"``, a cascade)."""

    source: str
    target: str
    gain: float = 0.5
    tau: float = 60.0
    delay: float = 0.0
    kind: str = "load"


@dataclasses.dataclass(frozen=True)
class External:
    """A periodic load from outside the loops: ``shape`` "sine" or "square", ``amplitude``
    (fraction of span at each loop's process input, times ``gains``), ``period`` (s),
    through a first-order lag ``tau`` (s)."""

    name: str
    loops: tuple[str, ...]
    gains: tuple[float, ...]
    amplitude: float = 0.02
    period: float = 600.0
    shape: str = "square"
    tau: float = 30.0


@dataclasses.dataclass(frozen=True)
class Indicator:
    """A measured signal of no loop: ``source`` (a loop, or an external load) through
    ``gain`` and a first-order lag ``tau`` (s), plus white noise ``noise_sd``, written in
    steps of ``quantum`` (0: not quantised). Of a loop it reads ``signal``: "pv" its
    measured PV, "process" its process value before the loop's own sensor lag, "valve" its
    valve's position (a flow meter right after the valve: % of span as fraction of span)."""

    name: str
    source: str
    gain: float = 1.0
    tau: float = 30.0
    noise_sd: float = 0.05
    signal: str = "pv"
    quantum: float = 0.0


@dataclasses.dataclass(frozen=True)
class PlantScenario:
    """A plant and what is true of it: ``sources`` maps each oscillation's source (a loop
    name, or an external's name) to the loops it reaches."""

    name: str
    loops: tuple[PlantLoop, ...]
    links: tuple[Link, ...] = ()
    externals: tuple[External, ...] = ()
    indicators: tuple[Indicator, ...] = ()
    sources: dict[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)
    description: str = ""


@dataclasses.dataclass(frozen=True)
class PlantRecord:
    """One plant's signals on one time base (``ts``, s): OP (% of span) and PV per loop,
    the indicators, and the valve positions (% of span, not measured in a plant)."""

    scenario: PlantScenario
    ts: float
    op: dict[str, FloatArray]
    pv: dict[str, FloatArray]
    indicators: dict[str, FloatArray]
    vp: dict[str, FloatArray]


def _lag(tau: FloatArray, ts: float) -> FloatArray:
    """The discrete first-order lags' poles, exp(-ts / tau), by the C library's ``exp``
    one at a time: numpy's vector ``exp`` differs in the last bit on processors with AVX-512,
    and a sticky valve's limit cycle grows that bit into another trajectory (the demo's
    plant ran differently on AMD EPYC machines, issue 35)."""
    return np.array([math.exp(-ts / max(float(t), 1e-9)) for t in np.ravel(tau)],
                    dtype=np.float64).reshape(np.shape(tau))


@dataclasses.dataclass
class _Vector:
    """Every loop of every plant side by side, and the paths as index arrays into them."""

    loops: list[PlantLoop]
    owner: list[int]  # the plant of each loop
    link_src: list[int]
    link_tgt: list[int]
    links: list[Link]
    ext: list[External]
    ext_loop: list[int]  # (external, loop, gain) triples of where each external enters
    ext_of: list[int]
    ext_gain: list[float]
    ind: list[tuple[int, Indicator]]  # (plant, indicator)
    ind_loop: list[int]  # the loop an indicator reads, or -1
    ind_ext: list[int]  # the external it reads, or -1


def _vector(scenarios: Sequence[PlantScenario]) -> _Vector:
    v = _Vector([], [], [], [], [], [], [], [], [], [], [], [])
    for p, sc in enumerate(scenarios):
        index = {lp.name: len(v.loops) + i for i, lp in enumerate(sc.loops)}
        if len(index) != len(sc.loops):
            raise ParameterError("scenarios", f"{sc.name}: two loops share a name")
        v.loops.extend(sc.loops)
        v.owner.extend([p] * len(sc.loops))
        for ln in sc.links:
            if ln.source not in index or ln.target not in index:
                raise ParameterError("scenarios", f"{sc.name}: link {ln.source} -> "
                                     f"{ln.target} names a loop the plant does not have")
            if ln.kind not in ("load", "setpoint"):
                raise ParameterError("scenarios", f"{sc.name}: link kind must be 'load' or "
                                     f"'setpoint', was {ln.kind!r}")
            v.link_src.append(index[ln.source])
            v.link_tgt.append(index[ln.target])
            v.links.append(ln)
        ext_index = {}
        for ex in sc.externals:
            ext_index[ex.name] = len(v.ext)
            for name, g in zip(ex.loops, ex.gains, strict=True):
                v.ext_loop.append(index[name])
                v.ext_of.append(len(v.ext))
                v.ext_gain.append(g)
            v.ext.append(ex)
        for ind in sc.indicators:
            if ind.source not in index and ind.source not in ext_index:
                raise ParameterError("scenarios", f"{sc.name}: indicator {ind.name} reads "
                                     f"{ind.source!r}, neither a loop nor an external")
            if ind.signal not in SIGNALS:
                raise ParameterError("scenarios", f"{sc.name}: indicator {ind.name} reads "
                                     f"signal {ind.signal!r}, not one of {', '.join(SIGNALS)}")
            v.ind.append((p, ind))
            v.ind_loop.append(index.get(ind.source, -1))
            v.ind_ext.append(ext_index.get(ind.source, -1))
    return v


def simulate_plants(scenarios: Sequence[PlantScenario], *, duration: float, ts: float = 1.0,
                    sample: int = 1, warmup: float = 1800.0, seed: int = 0
                    ) -> list[PlantRecord]:
    """Simulate every plant for ``warmup + duration`` seconds at ``ts``; keep every
    ``sample``-th step of the last ``duration`` seconds. Deterministic for ``seed``."""
    if not scenarios:
        return []
    vec = _vector(scenarios)
    steps = round((warmup + duration) / ts)
    keep = round(warmup / ts)
    sim = _Simulation(vec, ts, np.random.default_rng(seed))
    n_out = (steps - keep + sample - 1) // sample
    out = {key: np.empty((n_out, size)) for key, size in
           (("op", len(vec.loops)), ("pv", len(vec.loops)), ("vp", len(vec.loops)),
            ("ind", len(vec.ind)))}
    j = 0
    for step in range(steps):
        op, pv, vp, ind = sim.step(step * ts)
        if step >= keep and (step - keep) % sample == 0:
            out["op"][j], out["pv"][j], out["vp"][j], out["ind"][j] = op, pv, vp, ind
            j += 1
    return _records(scenarios, vec, out, ts * sample)


def _records(scenarios: Sequence[PlantScenario], vec: _Vector, out: dict[str, FloatArray],
             ts: float) -> list[PlantRecord]:
    records = []
    for p, sc in enumerate(scenarios):
        idx = [i for i, o in enumerate(vec.owner) if o == p]
        names = [vec.loops[i].name for i in idx]
        ind = {ind.name: out["ind"][:, i].copy() for i, (q, ind) in enumerate(vec.ind)
               if q == p}
        records.append(PlantRecord(
            sc, ts, {n: out["op"][:, i].copy() for n, i in zip(names, idx, strict=True)},
            {n: out["pv"][:, i].copy() for n, i in zip(names, idx, strict=True)}, ind,
            {n: out["vp"][:, i].copy() for n, i in zip(names, idx, strict=True)}))
    return records


class _Simulation:
    """The state of every loop, link, external and indicator; :meth:`step` advances all."""

    def __init__(self, v: _Vector, ts: float, rng: np.random.Generator) -> None:
        def col(name: str, dtype: type = float) -> np.ndarray:
            return np.array([getattr(x, name) for x in v.loops], dtype=dtype)

        self.ts, self.rng, n = ts, rng, len(v.loops)
        self.kc, self.ti, integ = col("kc"), col("ti"), col("integrating", bool)
        self.a = np.where(integ, 1.0, _lag(col("tau"), ts))
        self.b = np.where(integ, col("kp") * ts, col("kp") * (1.0 - self.a))
        self.delay = np.maximum(np.rint(col("theta") / ts).astype(np.intp), 0)
        self.fs, self.fd, self.k = col("fs"), col("fd"), col("k")
        self.has_valve, self.noise = col("valve", bool), col("noise_sd")
        self.sp_step = col("sp_step")
        self.sensor_c, self.sensor = _lag(col("sensor_tau"), ts), np.full(n, 50.0)
        self.quantum = col("quantum")
        self.load_sd, self.load_c = col("load_sd"), _lag(col("load_tau"), ts)
        self.hist = np.zeros((int(self.delay.max()) + 1, n))
        self.rows = np.arange(n)
        self.y, self.integral, self.load = np.zeros(n), np.zeros(n), np.zeros(n)
        self.x, self.op = np.full(n, 0.5), np.full(n, 0.5)
        # links: source, target, kind, lag, delay
        self.l_src, self.l_tgt = np.array(v.link_src, np.intp), np.array(v.link_tgt, np.intp)
        self.l_load = np.array([ln.kind == "load" for ln in v.links], dtype=bool)
        self.l_gain = np.array([ln.gain for ln in v.links])
        self.l_c = _lag(np.array([ln.tau for ln in v.links]), ts)
        self.l_delay = np.array([round(ln.delay / ts) for ln in v.links], dtype=np.intp)
        self.l_hist = np.zeros((int(self.l_delay.max(initial=0)) + 1, len(v.links)))
        self.l_state = np.zeros(len(v.links))
        # externals, and where they enter
        self.e_amp = np.array([ex.amplitude for ex in v.ext])
        self.e_period = np.array([ex.period for ex in v.ext])
        self.e_square = np.array([ex.shape == "square" for ex in v.ext], dtype=bool)
        self.e_c = _lag(np.array([ex.tau for ex in v.ext]), ts)
        self.e_state = np.zeros(len(v.ext))
        self.e_loop, self.e_of = np.array(v.ext_loop, np.intp), np.array(v.ext_of, np.intp)
        self.e_gain = np.array(v.ext_gain)
        # indicators
        self.i_loop, self.i_ext = np.array(v.ind_loop, np.intp), np.array(v.ind_ext, np.intp)
        self.i_gain = np.array([ind.gain for _, ind in v.ind])
        self.i_signal = np.array([SIGNALS.index(ind.signal) for _, ind in v.ind], np.intp)
        self.i_quantum = np.array([ind.quantum for _, ind in v.ind])
        self.i_noise = np.array([ind.noise_sd for _, ind in v.ind])
        self.i_c = _lag(np.array([ind.tau for _, ind in v.ind]), ts)
        self.i_state = np.zeros(len(v.ind))
        self.k_step = 0

    def step(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        n = self.y.size
        process = 50.0 + 100.0 * self.y
        self.sensor = self.sensor_c * self.sensor + (1.0 - self.sensor_c) * process
        pv = self.sensor + self.noise * self.rng.standard_normal(n)
        wave = np.sin(2.0 * np.pi * t / self.e_period)
        raw = self.e_amp * np.where(self.e_square, np.sign(wave), wave)
        self.e_state = self.e_c * self.e_state + (1.0 - self.e_c) * raw
        # each link's source signal (PV deviation, or OP about mid-span), delayed, lagged
        src = np.where(self.l_load, (pv[self.l_src] - 50.0) / 100.0,
                       100.0 * (self.op[self.l_src] - 0.5))
        ptr = self.k_step % self.l_hist.shape[0]
        self.l_hist[ptr] = src
        delayed = self.l_hist[(ptr - self.l_delay) % self.l_hist.shape[0],
                              np.arange(src.size)]
        self.l_state = self.l_c * self.l_state + (1.0 - self.l_c) * delayed
        push = self.l_gain * self.l_state
        sp = 50.0 + (self.sp_step if t >= 60.0 else 0.0) + np.bincount(
            self.l_tgt[~self.l_load], push[~self.l_load], minlength=n).astype(np.float64)
        into = np.bincount(self.l_tgt[self.l_load], push[self.l_load], minlength=n) + \
            np.bincount(self.e_loop, self.e_gain * self.e_state[self.e_of], minlength=n)
        vp = self._control(sp, pv)
        self.load = self.load_c * self.load + np.sqrt(1.0 - self.load_c ** 2) * \
            self.load_sd * self.rng.standard_normal(n)
        ptr = self.k_step % self.hist.shape[0]
        self.hist[ptr] = np.where(self.has_valve, vp - 0.5, 0.0) + into + self.load
        u_d = self.hist[(ptr - self.delay) % self.hist.shape[0], self.rows]
        self.y = self.a * self.y + self.b * u_d
        self.k_step += 1
        return (_steps(100.0 * self.op, self.quantum), _steps(pv, self.quantum), 100.0 * vp,
                self._indicators(pv, process))

    def _control(self, sp: FloatArray, pv: FloatArray) -> FloatArray:
        """Positional PI with conditional integration, OP clamped to the span; He's valve."""
        e = (sp - pv) / 100.0
        integral = self.integral + e * self.ts / self.ti
        raw = 0.5 + self.kc * (e + integral)
        self.op = np.clip(raw, 0.0, 1.0)
        winding = (raw != self.op) & (np.sign(e) == np.sign(raw - self.op))
        self.integral = np.where(winding, self.integral, integral)
        force = self.op - self.x
        slip = np.abs(force) > self.fs
        self.x = np.where(slip, self.x + self.k * (force - np.sign(force) * self.fd), self.x)
        return self.x

    def _indicators(self, pv: FloatArray, process: FloatArray) -> FloatArray:
        ext = np.append(self.e_state, 0.0)  # index -1: no external
        of_loop = np.stack(((pv - 50.0) / 100.0, (process - 50.0) / 100.0, self.x - 0.5))
        raw = np.where(self.i_loop >= 0, of_loop[self.i_signal, self.i_loop], ext[self.i_ext])
        self.i_state = self.i_c * self.i_state + (1.0 - self.i_c) * raw
        return _steps(50.0 + 100.0 * self.i_gain * self.i_state
                      + self.i_noise * self.rng.standard_normal(raw.size), self.i_quantum)


def _steps(x: FloatArray, quantum: FloatArray) -> FloatArray:
    """``x`` in steps of ``quantum`` where that is above 0."""
    q = np.where(quantum > 0, quantum, 1.0)
    return np.asarray(np.where(quantum > 0, np.round(x / q) * q, x))
