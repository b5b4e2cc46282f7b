"""Simulated PLC: a Modbus TCP server whose OP/PV registers are driven by stiction's
closed-loop simulator, sample by sample, in real time or ``time_scale`` times faster.

Config format (YAML; documented for users in docs/plc-sim.md)::

    listen: 127.0.0.1:5502      # where the simulated PLC serves (port 0: any free port)
    unit_id: 1                  # answered unit id (0: any)
    ts: 1.0                     # sample time, process s (the gateway's poll_interval_s)
    time_scale: 1.0             # process seconds per wall second
    seed: 0                     # random seed (noise, random loads)
    word_order: big             # of the float32 registers
    loops:
      - name: FIC101
        scenario: table4-case2  # any stiction scenario name (`stiction simulate --help`)
        noise: 0.05             # PV measurement noise, standard deviation in PV units
        params: {fs: 0.3}       # optional scenario overrides (fs, fd, kc, ti, tau, ...)
        address: 0              # optional; default: right after the previous loop
        window_s: 3600          # optional, only for --write-gateway-config
        result_address: 0       # optional, only for --write-gateway-config

Each loop takes 4 registers from ``address``: OP float32 (% of valve span) then PV float32
(process units), served alike as holding and input registers (read-only). Loops are grouped
by valve class into :class:`stiction.simulate.LoopBank` s whose parameters are arrays, so a
step of 10,000 loops costs a few dozen numpy operations. Each loop gets its scenario's
setpoint step (``sp_step`` at ``sp_step_time``) so sticky loops start their limit cycle.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import itertools
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from stiction.scenarios import SCENARIOS, Scenario, scenario
from stiction.simulate import LoopBank, LoopParams

from . import _schema as s
from ._schema import MISSING, Problems, Section
from .config import RESULT_BLOCK_SIZE
from .errors import ConfigError
from .inputs.modbus import encode_values
from .result_server import RegisterServer

__all__ = ["PlcSim", "SimConfig", "SimLoop", "gateway_config", "load_sim_config",
           "parse_sim_config"]

log = logging.getLogger(__name__)

REGISTERS_PER_LOOP = 4


@dataclasses.dataclass(frozen=True)
class SimLoop:
    name: str
    scenario: Scenario
    noise: float = 0.0
    address: int = 0
    window_s: float | None = None
    result_address: int | None = None


@dataclasses.dataclass(frozen=True)
class SimConfig:
    loops: tuple[SimLoop, ...]
    listen: tuple[str, int] = ("127.0.0.1", 5502)
    unit_id: int = 1
    ts: float = 1.0
    time_scale: float = 1.0
    seed: int = 0
    word_order: str = "big"


def load_sim_config(path: str | Path) -> SimConfig:
    source = str(path)
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError([f"{source}: cannot read: {exc.strerror or exc}"]) from None
    except yaml.YAMLError as exc:
        raise ConfigError([f"{source}: invalid YAML: {str(exc).replace(chr(10), ' ')}"]) from None
    return parse_sim_config(data, source)


def parse_sim_config(data: Any, source: str = "<plc-sim config>") -> SimConfig:
    problems = Problems(source)
    top = Section(problems, "top level", data)
    if data is None:
        problems.add("top level", None, "the file is empty")
    d = SimConfig(())
    listen = top.opt("listen", s.listen_address, d.listen)
    unit_id = top.opt("unit_id", s.integer(0, 247), d.unit_id)
    ts = top.opt("ts", s.number(positive=True), d.ts)
    time_scale = top.opt("time_scale", s.number(positive=True), d.time_scale)
    seed = top.opt("seed", s.integer(0), d.seed)
    word_order = top.opt("word_order", s.choice(("big", "little")), d.word_order)
    raw_loops = top.req("loops", _nonempty_list)
    loops: list[SimLoop] = []
    names: set[str] = set()
    next_address = 0
    used: list[tuple[int, str]] = []
    for i, raw in enumerate(raw_loops if raw_loops is not MISSING else []):
        name = raw.get("name") if isinstance(raw, dict) else None
        sec = Section(problems, f"loop {name}" if isinstance(name, str) else f"loops[{i}]", raw)
        if not sec.valid:
            continue
        lname = sec.req("name", s.string)
        sc_name = sec.req("scenario", s.choice(tuple(SCENARIOS)))
        noise = sec.opt("noise", s.number(non_negative=True), 0.0)
        params = sec.opt("params", _mapping, {})
        address = sec.opt("address", s.integer(0, 65536 - REGISTERS_PER_LOOP), next_address)
        window = sec.opt("window_s", s.number(positive=True), None)
        result_address = sec.opt("result_address", s.integer(0, 65536 - RESULT_BLOCK_SIZE),
                                 None)
        sec.done()
        sc: Any = MISSING
        if sc_name is not MISSING and params is not MISSING:
            try:
                sc = scenario(sc_name, **params)
            except Exception as exc:  # ParameterError, TypeError from bad values
                sec.error("params", str(exc))
        if lname is not MISSING:
            if lname in names:
                sec.error("name", f"duplicate loop name {lname!r}")
            names.add(lname)
        if MISSING in (lname, sc, noise, address, window, result_address):
            continue
        used.append((address, lname))
        next_address = address + REGISTERS_PER_LOOP
        loops.append(SimLoop(lname, sc, noise, address, window, result_address))
    used.sort()
    for (a0, n0), (a1, n1) in itertools.pairwise(used):
        if a1 < a0 + REGISTERS_PER_LOOP:
            problems.add(f"loop {n1}", "address", f"registers {a1}..{a1 + 3} overlap loop {n0}")
    top.done()
    if not problems.ok:
        raise ConfigError(problems.lines)
    return SimConfig(tuple(loops), listen, unit_id, ts, time_scale, seed, word_order)


def _nonempty_list(value: Any) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise TypeError("must be a non-empty list")
    return value


def _mapping(value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TypeError("must be a mapping")
    return value


# ------------------------------------------------------------------------ simulation


@dataclasses.dataclass
class _Bank:
    bank: LoopBank
    rows: NDArray[np.intp]  # loop indices in config order
    sp_base: NDArray[np.float64]
    sp_step: NDArray[np.float64]
    sp_time: NDArray[np.float64]


def _build_banks(cfg: SimConfig) -> list[_Bank]:
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
        n = len(cfg.loops)
        addr = np.array([lp.address for lp in cfg.loops], dtype=np.intp)
        size = int(addr.max()) + REGISTERS_PER_LOOP if n else REGISTERS_PER_LOOP
        self.image = np.zeros(size, dtype=np.uint16)
        self._op_idx = addr[:, None] + np.arange(2)
        self._pv_idx = addr[:, None] + 2 + np.arange(2)
        self.banks = _build_banks(cfg)
        self.op = np.zeros(n)
        self.pv = np.zeros(n)
        self.steps = 0
        host, port = cfg.listen
        self.server = RegisterServer({"holding": self.image, "input": self.image},
                                     host=host, port=port, unit_id=cfg.unit_id)
        self._task: asyncio.Task[None] | None = None
        self.period = cfg.ts / cfg.time_scale  # wall seconds per step
        self.phase_ref: float | None = None  # loop.time() of the step grid, once running
        self.step()  # registers hold the first sample before anyone reads

    @property
    def port(self) -> int:
        return self.server.port

    def step(self) -> None:
        """Advance every loop one sample and publish OP/PV in the registers."""
        for b in self.banks:
            t = b.bank.t
            sp = b.sp_base + np.where(t >= b.sp_time, b.sp_step, 0.0)
            out = b.bank.step(sp)
            self.op[b.rows] = out.op
            self.pv[b.rows] = out.pv
        wo = self.cfg.word_order
        self.image[self._op_idx] = encode_values(self.op, "float32", wo)
        self.image[self._pv_idx] = encode_values(self.pv, "float32", wo)
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
            due += behind * period

    async def __aenter__(self) -> PlcSim:
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
        await self.server.stop()


def gateway_config(cfg: SimConfig, *, port: int | None = None, host: str | None = None,
                   analysis_interval_s: float = 300.0, metrics_listen: str = "127.0.0.1:9108",
                   result_listen: str = "127.0.0.1:5020") -> dict[str, Any]:
    """The gateway config (as a YAML-ready dict) that reads every loop of ``cfg``."""
    loops: list[dict[str, Any]] = []
    next_result = 0
    for lp in cfg.loops:
        sc = lp.scenario
        result_address = lp.result_address if lp.result_address is not None else next_result
        next_result = result_address + RESULT_BLOCK_SIZE
        loops.append({
            "name": lp.name, "device": "plc-sim",
            "op": {"address": lp.address, "type": "float32"},
            "pv": {"address": lp.address + 2, "type": "float32"},
            "process": "integrating" if sc.integrating else "self-regulating",
            "kp": sc.kp, "delay_s": sc.theta,
            "window_s": lp.window_s if lp.window_s is not None else 3600.0,
            "result_address": result_address,
        })
    sim_host, sim_port = cfg.listen
    return {
        "gateway": {"analysis_interval_s": analysis_interval_s,
                    "time_scale": cfg.time_scale},
        "metrics": {"listen": metrics_listen},
        "modbus_server": {"listen": result_listen, "unit_id": 1, "word_order": "big"},
        "devices": [{
            "name": "plc-sim", "protocol": "modbus",
            "host": host or sim_host, "port": port if port is not None else sim_port,
            "unit_id": cfg.unit_id or 1, "poll_interval_s": cfg.ts,
            "timeout_s": 1.0, "max_registers_per_request": 125,
            "word_order": cfg.word_order,
        }],
        "loops": loops,
    }


def dump_yaml(data: dict[str, Any]) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


async def serve(cfg: SimConfig, stop: asyncio.Event) -> None:
    async with PlcSim(cfg) as sim:
        log.info("plc-sim: %d loops on %s:%d, ts %g s, time_scale %g", len(cfg.loops),
                 cfg.listen[0], sim.port, cfg.ts, cfg.time_scale)
        await stop.wait()


def loop_names(cfg: SimConfig) -> Sequence[str]:
    return [lp.name for lp in cfg.loops]
