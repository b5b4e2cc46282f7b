"""Simulated PLC: a Modbus TCP server whose OP/PV registers are driven by stiction's
closed-loop simulator, sample by sample, in real time or ``time_scale`` times faster.

Config format (YAML; documented for users in docs/plc-sim.md)::

    listen: 127.0.0.1:5502      # where the simulated PLC serves (port 0: any free port)
    unit_id: 1                  # answered unit id (0: any)
    ts: 1.0                     # sample time, process s (the gateway's poll_interval_s)
    time_scale: 1.0             # process seconds per wall second
    seed: 0                     # random seed (noise, random loads)
    word_order: big             # of the float32 registers
    protocol: modbus            # or opcua: serve ns=2;s=<loop>.OP / .PV over OPC UA instead
    opcua:                      # optional, only with protocol: opcua (absent: None/None)
      certificate: pki/server.der   # server certificate and key (opcua-cert --server)
      private_key: pki/server.pem
      policy: Basic256Sha256        # offered policy and mode
      mode: SignAndEncrypt
      username: gateway             # optional: require this login ...
      password_file: secrets/opcua.pw   # ... with the password on this file's first line
      trusted_clients: pki/trusted-clients/  # optional: accept only these client certs
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

from gateway.config import RESULT_BLOCK_SIZE, RESULT_LOOPS_PER_UNIT
from gateway.config import schema as s
from gateway.config.schema import MISSING, Problems, Section
from gateway.errors import ConfigError
from gateway.inputs.modbus.client import encode_values
from gateway.wire.registers import RegisterServer
from stiction.scenarios import SCENARIOS, Scenario, scenario
from stiction.simulate import LoopBank, LoopParams

from .opcua import POLICY_TYPES, OpcUaPlcServer, ServerSecurity

__all__ = ["PlcSim", "SimConfig", "SimLoop", "gateway_config", "load_sim_config",
           "parse_sim_config"]

log = logging.getLogger("gateway.plc_sim")

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
    protocol: str = "modbus"
    opcua: ServerSecurity | None = None  # with protocol opcua: None means None/None


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
    protocol = top.opt("protocol", s.choice(("modbus", "opcua")), d.protocol)
    opcua: Any = None
    if top.has("opcua"):
        base = Path(source).parent if Path(source).is_file() else Path.cwd()
        opcua = _parse_opcua(top.sub("opcua"), base)
        if protocol != "opcua":
            top.error("opcua", "needs 'protocol: opcua'")
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
    return SimConfig(tuple(loops), listen, unit_id, ts, time_scale, seed, word_order,
                     protocol, opcua)


def _parse_opcua(sec: Section, base: Path) -> ServerSecurity | Any:
    """The simulated PLC's OPC UA security (paths relative to the config's directory)."""

    def path(value: Any) -> Path:
        p = Path(s.string(value)).expanduser()
        return p if p.is_absolute() else base / p

    def existing(value: Any) -> Path:
        p = path(value)
        if not p.exists():
            raise ValueError(f"file not found: {value}")
        return p

    cert = sec.req("certificate", existing)
    key = sec.req("private_key", existing)
    policy = sec.opt("policy", s.choice(tuple({k[0] for k in POLICY_TYPES} - {"None"})),
                     "Basic256Sha256")
    mode = sec.opt("mode", s.choice(("Sign", "SignAndEncrypt")), "SignAndEncrypt")
    user = sec.opt("username", s.string, None)
    pw_file = sec.opt("password_file", existing, None)
    trusted = sec.opt("trusted_clients", existing, None)
    sec.done()
    if (user is None) != (pw_file is None):
        sec.error(None, "username and password_file go together")
        return MISSING
    if MISSING in (cert, key, policy, mode, user, pw_file, trusted):
        return MISSING
    users = None
    if user is not None:
        users = {user: pw_file.read_text(encoding="utf-8").splitlines()[0]}
    return ServerSecurity(cert, key, policies=((policy, mode),), users=users,
                          trusted_clients=trusted)


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
        self.opcua: OpcUaPlcServer | None = None
        if cfg.protocol == "opcua":
            self.opcua = OpcUaPlcServer([lp.name for lp in cfg.loops], host=host, port=port,
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
            if self.opcua is not None:
                await self.opcua.update(self.op, self.pv)
            due += behind * period

    async def __aenter__(self) -> PlcSim:
        if self.opcua is not None:
            await self.opcua.start()
            await self.opcua.update(self.op, self.pv)
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
        if self.opcua is not None:
            await self.opcua.stop()
        else:
            await self.server.stop()

MAX_RESULT_ADDRESS = (RESULT_LOOPS_PER_UNIT - 1) * RESULT_BLOCK_SIZE
"""The last block start that :func:`gateway_config` fills on one unit id (65,500)."""


def assign_result_blocks(loops: Sequence[dict[str, Any]], unit_id: int = 1) -> None:
    """Give gateway-config loop dicts consecutive result blocks, as :func:`gateway_config`
    does: 3,276 per unit id from ``unit_id`` on (``result_unit_id`` written only where it is
    not ``unit_id``, i.e. not ``modbus_server.unit_id``). Replaces any they had."""
    for i, lp in enumerate(loops):
        unit, k = divmod(i, RESULT_LOOPS_PER_UNIT)
        lp["result_address"] = k * RESULT_BLOCK_SIZE
        lp.pop("result_unit_id", None)
        if unit:
            lp["result_unit_id"] = unit_id + unit


def gateway_config(cfg: SimConfig, *, port: int | None = None, host: str | None = None,
                   analysis_interval_s: float = 300.0, metrics_listen: str = "127.0.0.1:9108",
                   result_listen: str = "127.0.0.1:5020", result_unit_id: int = 1,
                   opcua_security: dict[str, Any] | None = None) -> dict[str, Any]:
    """The gateway config (as a YAML-ready dict) that reads every loop of ``cfg``.

    Result blocks follow each other from address 0 on ``modbus_server.unit_id``
    (``result_unit_id``); when a unit id's register space is full (3,276 loops) they go on
    from address 0 of the next unit id, written as the loop's ``result_unit_id``. A loop
    with its own ``result_address`` keeps it, on the unit id being filled.

    With ``protocol: opcua`` the device is an OPC UA one; its ``security`` section is
    ``opcua_security`` if given, else (for a secured plc-sim) one with the plc-sim's policy,
    mode, certificate and login, and the usual client paths (pki/client.der, pki/client.pem,
    pki/trusted/) to be created with ``stiction-gateway opcua-cert``."""
    loops: list[dict[str, Any]] = []
    unit, next_result = result_unit_id, 0
    for lp in cfg.loops:
        sc = lp.scenario
        if lp.result_address is not None:  # on the current unit id
            result_address = lp.result_address
        else:
            if next_result > MAX_RESULT_ADDRESS:  # this unit id is full: the next one
                unit, next_result = unit + 1, 0
            result_address = next_result
        next_result = result_address + RESULT_BLOCK_SIZE
        loops.append({
            "name": lp.name, "device": "plc-sim",
            "op": ({"address": lp.address, "type": "float32"} if cfg.protocol == "modbus"
                   else {"node": f"ns=2;s={lp.name}.OP"}),
            "pv": ({"address": lp.address + 2, "type": "float32"} if cfg.protocol == "modbus"
                   else {"node": f"ns=2;s={lp.name}.PV"}),
            "process": "integrating" if sc.integrating else "self-regulating",
            "kp": sc.kp, "delay_s": sc.theta,
            "window_s": lp.window_s if lp.window_s is not None else 3600.0,
            "result_address": result_address,
            **({"result_unit_id": unit} if unit != result_unit_id else {}),
        })
    sim_host, sim_port = cfg.listen
    out = {
        "gateway": {"analysis_interval_s": analysis_interval_s,
                    "time_scale": cfg.time_scale},
        "metrics": {"listen": metrics_listen},
        "modbus_server": {"listen": result_listen, "unit_id": result_unit_id,
                          "word_order": "big"},
        "devices": [{
            "name": "plc-sim", "protocol": "modbus",
            "host": host or sim_host, "port": port if port is not None else sim_port,
            "unit_id": cfg.unit_id or 1, "poll_interval_s": cfg.ts,
            "timeout_s": 1.0, "max_registers_per_request": 125,
            "word_order": cfg.word_order,
        }],
        "loops": loops,
    }
    if cfg.protocol == "opcua":
        device: dict[str, Any] = {
            "name": "plc-sim", "protocol": "opcua",
            "endpoint": f"opc.tcp://{host or sim_host}:{port if port is not None else sim_port}",
            "poll_interval_s": cfg.ts, "timeout_s": 1.0,
        }
        sec = cfg.opcua
        if opcua_security is not None:
            device["security"] = opcua_security
        elif sec is not None:
            policy, mode = sec.policies[0]
            device["security"] = {
                "policy": policy, "mode": mode, "certificate": "pki/client.der",
                "private_key": "pki/client.pem", "server_certificate": str(sec.certificate),
                "trust_store": "pki/trusted/"}
            if sec.users:
                device["security"]["username"] = next(iter(sec.users))
                device["security"]["password_file"] = "secrets/opcua.pw"
        out["devices"] = [device]
    return out


def dump_yaml(data: dict[str, Any]) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


async def serve(cfg: SimConfig, stop: asyncio.Event) -> None:
    async with PlcSim(cfg) as sim:
        log.info("plc-sim: %d loops on %s:%d, ts %g s, time_scale %g", len(cfg.loops),
                 cfg.listen[0], sim.port, cfg.ts, cfg.time_scale)
        await stop.wait()


def loop_names(cfg: SimConfig) -> Sequence[str]:
    return [lp.name for lp in cfg.loops]
