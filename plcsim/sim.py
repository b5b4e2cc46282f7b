"""Simulated PLC: a Modbus TCP server whose OP/PV registers are driven by stiction's
closed-loop simulator, sample by sample, in real time or ``time_scale`` times faster.

The config is :mod:`plcsim.config` (docs/plc-sim.md). Each loop takes 4 registers from its
``address``: OP float32 (% of valve span) then PV float32 (process units), served alike as
holding and input registers (read-only). After every loop's block, each single loop's valve
position (float32, % of valve span: the simulated valve's own) at
``SimConfig.position_address(k)``, as a smart positioner reports it. Loops are grouped by
valve class into :class:`stiction.models.simulate.LoopBank` s whose parameters are
arrays, so a step of 10,000 loops costs a few dozen numpy operations. Each loop gets its
scenario's setpoint step (``sp_step`` at ``sp_step_time``) so sticky loops start their limit
cycle. With ``step_test`` one loop is held in manual and steps through a step test
(:mod:`plcsim.steptest`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging

import numpy as np
from numpy.typing import NDArray

from gateway.wire.codec import encode_values
from gateway.wire.registers import RegisterServer
from stiction.models.simulate import LoopBank, LoopParams

from .config import REGISTERS_PER_LOOP, SimConfig
from .opcua import OpcUaPlcServer
from .plant import PlantFeed
from .steptest import StepTestPlayer, default_hold_s

__all__ = ["PlcSim", "build_banks", "serve"]

log = logging.getLogger("gateway.plc_sim")


@dataclasses.dataclass
class _Bank:
    bank: LoopBank
    rows: NDArray[np.intp]  # loop indices in config order
    sp_base: NDArray[np.float64]
    sp_step: NDArray[np.float64]
    sp_time: NDArray[np.float64]


def build_banks(cfg: SimConfig) -> list[_Bank]:
    groups: dict[type, list[int]] = {}
    for i, lp in enumerate(cfg.loops):
        groups.setdefault(type(lp.scenario.valve()), []).append(i)
    banks = []
    for k, (cls, members) in enumerate(groups.items()):
        scs = [cfg.loops[i].scenario for i in members]
        valves = [sc.valve() for sc in scs]
        valve = cls(**{f.name: np.array([getattr(v, f.name) for v in valves], dtype=float)
                       for f in dataclasses.fields(cls)})
        params = [sc.loop_params(cfg.loops[i].noise) for sc, i in zip(scs, members, strict=True)]
        lparams = LoopParams(**{f.name: np.array([getattr(p, f.name) for p in params])
                           for f in dataclasses.fields(LoopParams)})
        bank = LoopBank(len(members), lparams, valve, ts=cfg.ts, seed=cfg.seed + k)
        banks.append(_Bank(bank, np.array(members, dtype=np.intp), bank.pv0.copy(),
                           np.array([sc.sp_step for sc in scs]),
                           np.array([sc.sp_step_time for sc in scs])))
    return banks


class PlcSim:
    """The simulated PLC; ``async with PlcSim(cfg) as sim:`` serves and steps in real time
    (scaled). ``sim.port`` is the bound port, ``sim.server.requests`` counts reads served."""

    def __init__(self, cfg: SimConfig) -> None:
        self.cfg = cfg
        self.singles = len(cfg.loops)
        plant_addr = [p.address + REGISTERS_PER_LOOP * k for p in cfg.plants
                      for k in range(len(p.loops))]
        n = self.singles + len(plant_addr)
        addr = np.array([lp.address for lp in cfg.loops] + plant_addr, dtype=np.intp)
        size = int(addr.max()) + REGISTERS_PER_LOOP if n else REGISTERS_PER_LOOP
        base = cfg.position_base
        self.image = np.zeros(max(size, base + 2 * self.singles), dtype=np.uint16)
        self._op_idx = addr[:, None] + np.arange(2)
        self._pv_idx = addr[:, None] + 2 + np.arange(2)
        self._pos_idx = base + 2 * np.arange(self.singles)[:, None] + np.arange(2)
        self.banks = build_banks(cfg)
        self.plants = PlantFeed(cfg.plants, cfg.ts, cfg.seed)
        # the loop under a step test: (its bank, its place there, the player)
        self.step_test: tuple[int, int, StepTestPlayer] | None = None
        if cfg.step_test is not None:
            row = cfg.loop_names().index(cfg.step_test.loop)
            sc = cfg.loops[row].scenario
            hold = cfg.step_test.hold_s or default_hold_s(sc.tau, sc.theta, sc.integrating,
                                                          cfg.ts)
            for k, b in enumerate(self.banks):
                if row in b.rows:
                    place = int(np.flatnonzero(b.rows == row)[0])
                    self.step_test = (k, place, StepTestPlayer(cfg.step_test, hold))
        self.op = np.zeros(n)
        self.pv = np.zeros(n)
        self.position = np.full(n, np.nan)  # the valves' (plant loops: none)
        self.steps = 0
        host, port = cfg.listen
        self.server = RegisterServer({"holding": self.image, "input": self.image},
                                     host=host, port=port, unit_id=cfg.unit_id)
        self.opcua: OpcUaPlcServer | None = None
        if cfg.protocol == "opcua":
            self.opcua = OpcUaPlcServer(cfg.loop_names(), host=host, port=port,
                                        security=cfg.opcua)
        self._task: asyncio.Task[None] | None = None
        self.period = cfg.ts / cfg.time_scale  # wall seconds per step
        self.phase_ref: float | None = None  # loop.time() of the step grid, once running
        self.step()  # registers hold the first sample before anyone reads

    @property
    def port(self) -> int:
        return self.opcua.port if self.opcua is not None else self.server.port

    def step(self) -> None:
        """Advance every loop one sample and publish OP/PV in the registers."""
        for k, b in enumerate(self.banks):
            t = b.bank.t
            sp = b.sp_base + np.where(t >= b.sp_time, b.sp_step, 0.0)
            manual = None
            test = self.step_test if self.step_test and self.step_test[0] == k else None
            if test is not None:  # the OP automatic left (before any: the operating point)
                op_now = (float(self.op[b.rows[test[1]]]) if self.steps
                          else 100.0 * float(b.bank.x0[test[1]]))
                held = test[2].manual(t, op_now)
                if held is not None:
                    manual = np.full(b.rows.size, np.nan)
                    manual[test[1]] = held
            out = b.bank.step(sp, manual=manual)
            self.op[b.rows] = out.op
            self.pv[b.rows] = out.pv
            self.position[b.rows] = out.vp
            if test is not None and manual is not None:
                i = test[1]
                test[2].record(t, float(out.op[i]), float(out.pv[i]), float(out.vp[i]))
        self.op[self.singles:], self.pv[self.singles:] = self.plants.step()
        wo = self.cfg.word_order
        self.image[self._op_idx] = encode_values(self.op, "float32", wo)
        self.image[self._pv_idx] = encode_values(self.pv, "float32", wo)
        if self.singles:
            self.image[self._pos_idx] = encode_values(self.position[:self.singles], "float32",
                                                      wo)
        self.steps += 1

    async def run(self) -> None:
        """Step on an absolute schedule of ts / time_scale wall seconds; a late tick is
        caught up (at most 100 steps at once), so process time keeps pace with wall time."""
        loop = asyncio.get_running_loop()
        period = self.period
        due = loop.time() + period
        self.phase_ref = due
        while True:
            await asyncio.sleep(max(0.0, due - loop.time()))
            behind = int((loop.time() - due) // period) + 1
            for _ in range(min(behind, 100)):
                self.step()
            if self.opcua is not None:
                await self.opcua.update(self.op, self.pv, self.position)
            due += behind * period

    async def __aenter__(self) -> PlcSim:
        if self.opcua is not None:
            await self.opcua.start()
            await self.opcua.update(self.op, self.pv, self.position)
        else:
            await self.server.start()
        self._task = asyncio.create_task(self.run(), name="plc-sim")
        await asyncio.sleep(0)  # let run() fix its step grid (phase_ref)
        return self

    def mid_step(self) -> float:
        """A loop.time() instant half-way between two steps (see Gateway.align_polls)."""
        assert self.phase_ref is not None
        return self.phase_ref + self.period / 2

    async def __aexit__(self, *exc: object) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        if self.step_test is not None:
            self.step_test[2].close()
        if self.opcua is not None:
            await self.opcua.stop()
        else:
            await self.server.stop()


async def serve(cfg: SimConfig, stop: asyncio.Event) -> None:
    async with PlcSim(cfg) as sim:
        log.info("plc-sim: %d loops on %s:%d, ts %g s, time_scale %g", len(cfg.loops),
                 cfg.listen[0], sim.port, cfg.ts, cfg.time_scale)
        await stop.wait()
