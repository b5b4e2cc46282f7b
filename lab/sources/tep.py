"""tep-studio (revised Tennessee Eastman model, Ricker's decentralised PI control) for the
development corpus: the loop table, a mode's settled start, one closed-loop run, and the
model's sticky valve rebuilt in numpy (:func:`valve_command`, :func:`lagged`).

It imports tep-studio lazily (the ``bench`` extra): the rest of the lab reads its cached
runs without it.

What tep-studio 0.2.0 does (read in its source, checked by running it):

- Plant: the revised model ``temexd_mod`` (Bathelt, Ricker & Jelali 2015), integrated by a
  fixed-step RK4 at 0.0005 h. ``TennesseeEastmanProcess(ms_flag=...)``: tep-studio's default
  0x0F ignores IDV magnitudes (an IDV is on when >= 0.5); bit 0x80 scales each IDV by its
  value in [0, 1] (the model clips to that range), so this module sets 0x8F.
- Control: ``RickerMultiLoopController`` (Ricker 1996, mode-1 tuning for every mode), every
  loop sampled every 0.0005 h (1.8 s); the run here calls it at that period, as designed.
  Operating modes 1-6 are setpoint presets (``tep_studio.simulation.modes``); modes 3 and 6
  start from a bundled 90/10 state, the others from the base case and are steered there by
  rate-limited setpoints (about 24 h for modes 2 and 5), hence :func:`settle`; a run
  continues a settled mode from its snapshot, with its own noise seed (:func:`_start`).
- Sticky valves: in the model a valve's command ``vcv`` follows the controller output only
  when they differ by more than ``vst * ivst`` (% of span), then jumps to it; the valve
  position follows ``vcv`` through a first-order lag (5 s for XMV 10 and 11). That is He's
  model with fs = vst * ivst and fd = 0. ``ivst`` is IDV 14 (XMV 10, reactor cooling water),
  IDV 15 (XMV 11, condenser cooling water) and IDV 19 (XMV 5, 7, 8, 9) and ``vst`` is 2 %,
  so the IDV magnitude sets a band of 0-2 %. tep-studio has no setting for ``vst``: a band
  over 2 % is set by rewriting ``vst`` in the model's byte image (:func:`_start`,
  checked against its neighbours ``tgas`` 0.1 and ``tprod`` 0.25 before writing).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

CONTROL_H = 0.0005  # h: Ricker's controller period (1.8 s), also the recorded sample time
MS_FLAG = 0x8F  # tep-studio's 0x0F plus 0x80: IDV magnitudes scale the disturbances
MODES = ("mode1", "mode2", "mode3", "mode4", "mode5", "mode6")
SETTLE_H = 36.0  # a mode's settling run: modes 2 and 5 need about 24 h to reach their %G
STICKY_IDV = {14: (9,), 15: (10,), 19: (4, 6, 7, 8)}  # IDV -> XMV indices (0-based) it sticks
_VST = 2.0  # the model's band per unit IDV, % of span
_VST_AT = 1034  # index of vst[0] in the model's bytes as float64 (tep-studio 0.2.0)
_RNG_AT = 293  # index of the noise generator's state: after xmeas..xmv (264) and idv (29)
_DEFAULT_SEED = 1431655765


@dataclasses.dataclass(frozen=True)
class TepLoop:
    """A PI loop of Ricker's control whose output is a valve (XMV)."""

    name: str  # "XMV10"
    xmv: int  # 0-based index into the 12 manipulated variables
    pv: int  # 0-based index into the 41 measurements (XMEAS)
    controller: str  # tep-studio's loop name
    description: str
    setpoint: str  # how the setpoint is made (cascade)


LOOPS: tuple[TepLoop, ...] = (
    TepLoop("XMV1", 0, 1, "D feed", "D feed valve -> D feed flow (XMEAS 2)", "r2 x Fp"),
    TepLoop("XMV2", 1, 2, "E feed", "E feed valve -> E feed flow (XMEAS 3)", "r3 x Fp"),
    TepLoop("XMV3", 2, 0, "A feed", "A feed valve -> A feed flow (XMEAS 1)", "r1 x Fp"),
    TepLoop("XMV4", 3, 3, "C feed", "A+C feed valve -> A+C feed flow (XMEAS 4)", "r4 x Fp"),
    TepLoop("XMV6", 5, 9, "Purge", "purge valve -> purge flow (XMEAS 10)",
            "r5 x Fp, r5 from the reactor-pressure loop"),
    TepLoop("XMV7", 6, 13, "Sep flow", "separator underflow valve -> its flow (XMEAS 14)",
            "r6 x Fp, r6 from the separator-level loop"),
    TepLoop("XMV8", 7, 16, "Strip flow", "stripper underflow valve -> its flow (XMEAS 17)",
            "r7 x Fp, r7 from the stripper-level loop"),
    TepLoop("XMV10", 9, 8, "Reactor temperature",
            "reactor cooling-water valve -> reactor temperature (XMEAS 9)", "operator"),
    TepLoop("XMV11", 10, 10, "Separator temperature",
            "condenser cooling-water valve -> separator temperature (XMEAS 11)",
            "from the reactor-level loop (cascade)"),
)
"""XMV 5 (compressor recycle), 9 (stripper steam) and 12 (agitator) are held constant by
Ricker's control (XMV 5 moves only under the high-level override): no loop, no window."""



@dataclasses.dataclass(frozen=True)
class Settled:
    """A mode after :data:`SETTLE_H` hours of normal operation, to continue from: the
    model's snapshot (byte image, state, time), its last measurements and the controller."""

    mode: str
    snapshot: Any
    measurements: np.ndarray
    controller: Any

    @property
    def time(self) -> float:
        return float(self.snapshot.time)


@dataclasses.dataclass(frozen=True)
class RunArrays:
    """One run's recorded part, one row per controller period (1.8 s), loops in
    :data:`LOOPS` order; ``pos`` is the valve position (not measured in a plant)."""

    t: np.ndarray  # h since the run's start (the end of the mode's settling run)
    op: np.ndarray
    pv: np.ndarray
    sp: np.ndarray
    pos: np.ndarray
    xmeas: np.ndarray
    tripped: str  # "" or the model's shutdown message


def _tep() -> Any:
    import tep_studio  # noqa: PLC0415 - bench extra only
    from tep_studio.simulation import modes  # noqa: PLC0415

    return tep_studio, modes


def model_seed(seed: int) -> float:
    """The model's noise generator is g <- g * 9228907 mod 2**32: an even start shortens its
    period and 0 silences it, so run seed s starts it at the model's default + 2 s (odd)."""
    return float(_DEFAULT_SEED + 2 * seed)


def settle(mode: str) -> Settled:
    """Run ``mode`` for :data:`SETTLE_H` h without disturbance (seed 0)."""
    tep, modes = _tep()
    sim = tep.TennesseeEastmanProcess(ms_flag=MS_FLAG)
    meas, _ = sim.reset(mode=mode, seed=model_seed(0))
    ctl = tep.RickerMultiLoopController(setpoints=modes.mode_setpoints(mode),
                                        enable_overrides=True)
    ctl.reset(meas, time=0.0)
    for _ in range(round(SETTLE_H / CONTROL_H)):
        action, _ = ctl.compute_action(meas, time=sim.time)
        res = sim.advance(action, control_interval=CONTROL_H)
        meas = res.measurements
        if res.shutdown_status["terminated"]:
            raise RuntimeError(f"{mode} tripped while settling: {res.shutdown_status}")
    return Settled(mode, sim.snapshot(), meas.copy(), ctl)


def _start(settled: Settled, seed: int, vst: Mapping[int, float]) -> Any:
    """A plant that continues ``settled`` with its noise generator restarted from ``seed``
    and ``vst`` (% of span) for the XMV indices in it, both written into the model's bytes
    (tep-studio has no setting for either after a reset)."""
    tep, _ = _tep()
    sim = tep.TennesseeEastmanProcess(ms_flag=MS_FLAG)
    sim.reset(mode=settled.mode)  # the model's default seed: checks the layout
    fresh = np.frombuffer(sim.kernel.snapshot().model_bytes, dtype=np.float64)
    image = np.frombuffer(settled.snapshot.model_bytes, dtype=np.float64).copy()
    if not (np.allclose(fresh[_VST_AT - 2 : _VST_AT + 12], [0.1, 0.25] + [_VST] * 12)
            and np.array_equal(fresh[_RNG_AT : _RNG_AT + 3], [model_seed(0)] * 3)
            and np.array_equal(image[_VST_AT : _VST_AT + 12], [_VST] * 12)):
        raise RuntimeError("tep-studio's model layout is not the one this corpus knows")
    for xmv, band in vst.items():
        image[_VST_AT + xmv] = band
    image[_RNG_AT : _RNG_AT + 3] = model_seed(seed)  # g, measnoise, procdist
    sim.restore(dataclasses.replace(settled.snapshot, model_bytes=image.tobytes()))
    return sim


def idv_vector(idvs: Sequence[tuple[int, float]], bands: Mapping[int, float]) -> np.ndarray:
    """The 28 IDV values: each disturbance at its magnitude; a sticky valve's IDV at the
    magnitude that gives its band when the band is at most 2 %, else at 1."""
    vec = np.zeros(28)
    for idv, magnitude in idvs:
        vec[idv - 1] = magnitude
    for idv, xmvs in STICKY_IDV.items():
        sizes = [bands[x] for x in xmvs if x in bands]
        if sizes:
            vec[idv - 1] = min(1.0, max(sizes) / _VST)
    return vec


def model_bands(bands: Mapping[int, float]) -> dict[int, float]:
    """``vst`` per XMV index that :func:`idv_vector`'s magnitude turns into the wanted band
    (only those that differ from the model's 2 %)."""
    out: dict[int, float] = {}
    for xmvs in STICKY_IDV.values():
        sizes = [bands[x] for x in xmvs if x in bands]
        if sizes:
            magnitude = min(1.0, max(sizes) / _VST)
            out.update({x: bands.get(x, 0.0) / magnitude for x in xmvs})
    return {x: v for x, v in out.items() if v != _VST}


def run(settled: Settled, seed: int, idvs: Sequence[tuple[int, float]],
        bands: Mapping[int, float], *, onset_h: float, record_h: tuple[float, float]
        ) -> RunArrays:
    """Continue ``settled`` (its end is t = 0 here) with ``seed``: the disturbances ``idvs``
    ((IDV, magnitude)) and sticky valves ``bands`` ({XMV index: band, % of span}) from
    ``onset_h``; the rows from ``record_h[0]`` to ``record_h[1]`` h are returned."""
    sim = _start(settled, seed, model_bands(bands))
    meas = settled.measurements.copy()
    ctl = copy.deepcopy(settled.controller)
    t0 = settled.time
    on, off = idv_vector(idvs, bands), np.zeros(28)
    n, first, onset = (round(h / CONTROL_H) for h in (record_h[1], record_h[0], onset_h))
    cols, pvs = [lp.xmv for lp in LOOPS], [lp.pv for lp in LOOPS]
    rows = np.full((n - first, 4 * len(LOOPS) + 42), np.nan)
    tripped = ""
    for k in range(n):
        action, diag = ctl.compute_action(meas, time=sim.time)
        res = sim.advance(action, control_interval=CONTROL_H,
                          disturbances=on if k >= onset else off)
        meas = res.measurements
        if k >= first:
            rows[k - first] = np.concatenate((
                [sim.time - t0], res.implemented_action[cols], meas[pvs],
                _setpoints(diag), res.state[38:50][cols], meas))
        if res.shutdown_status["terminated"]:
            tripped = f"{res.shutdown_status['message']} at {sim.time - t0:.2f} h"
            break
    m = len(LOOPS)
    rows = rows[~np.isnan(rows[:, 0])]
    return RunArrays(rows[:, 0], rows[:, 1 : 1 + m], rows[:, 1 + m : 1 + 2 * m],
                     rows[:, 1 + 2 * m : 1 + 3 * m], rows[:, 1 + 3 * m : 1 + 4 * m],
                     rows[:, 1 + 4 * m :], tripped)


def valve_command(op: np.ndarray, band: float, start: float | None = None) -> np.ndarray:
    """The valve's command under the model's rule: it follows OP only when OP has moved
    more than ``band`` away from it, then jumps to OP (He's model with fs = band, fd = 0);
    one value per OP sample, starting at ``start`` (OP's first value if None)."""
    out = np.empty(op.size)
    v = float(op[0] if start is None else start)
    for k, u in enumerate(op.tolist()):
        if abs(u - v) > band:
            v = u
        out[k] = v
    return out


def lagged(command: np.ndarray, ts: float, tau: float, start: float) -> np.ndarray:
    """``command`` (held over each sample) through a first-order lag ``tau`` (s): the valve
    position the model integrates, sampled at the end of each period."""
    a = float(np.exp(-ts / tau))
    out = np.empty(command.size)
    x = start
    for k, c in enumerate(command.tolist()):
        x = a * x + (1.0 - a) * c
        out[k] = x
    return out


_RATIO = {"XMV1": "r2", "XMV2": "r3", "XMV3": "r1", "XMV4": "r4", "XMV6": "r5", "XMV7": "r6",
          "XMV8": "r7"}


def _setpoints(diag: Any) -> list[float]:
    """Each loop's setpoint at this step, from the controller's diagnostics."""
    out = []
    for lp in LOOPS:
        if lp.name in _RATIO:
            out.append(diag.ratios[_RATIO[lp.name]] * diag.fp)
        elif lp.name == "XMV10":
            out.append(diag.setpoints["reactor_temperature"])
        else:
            out.append(diag.setpoints["separator_temperature"])
    return out
