"""The simulated PLC's config (YAML; documented for users in docs/plc-sim.md)::

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
    step_test:                  # optional: hold one loop in manual, play a step test
      loop: FIC101              # (plcsim/steptest.py, docs/plc-sim.md)
      start_s: 600              # process s from the start (default 0)
      hold_s: 60                # process s per OP level (default: the loop's dead time
                                # plus four time constants, at least 30 s)
      record: step-test.csv     # optional: the test's recording (t, op, pv, position)
    plants:                     # optional: interacting loops with one source (plcsim/plant.py)
      - plant: sticky-feeds-two # a stiction.scenarios.plants.NAMED_PLANTS name
        prefix: U2.             # optional: loop names are prefix + the plant's loop names
        address: 100            # optional; default: right after the previous loop
        window_s: 3600          # optional, only for --write-gateway-config
        unit: U2                # optional, only for --write-gateway-config: the loops'
                                # plant unit (default: the prefix without its last '.',
                                # else the plant's name); the plant view keeps units apart
        duration_s: 14400       # optional: process s simulated at start, then replayed

It is read with the gateway's one validator (:mod:`gateway.config.schema`).
"""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path
from typing import Any

import yaml

from gateway.config import schema as s
from gateway.config.schema import MISSING, Problems, Section
from gateway.errors import ConfigError
from gateway.wire.results import RESULT_BLOCK_SIZE
from stiction.scenarios import SCENARIOS, Scenario, scenario
from stiction.scenarios.plants import NAMED_PLANTS

from .opcua import POLICY_TYPES, ServerSecurity
from .plant import DEFAULT_DURATION_S, SimPlant
from .steptest import StepTest

__all__ = ["REGISTERS_PER_LOOP", "SimConfig", "SimLoop", "load_sim_config", "parse_sim_config"]

REGISTERS_PER_LOOP = 4


@dataclasses.dataclass(frozen=True)
class SimLoop:
    """One simulated loop: its scenario, PV noise and first register; ``window_s`` and
    ``result_address`` only go into the gateway config written for it."""

    name: str
    scenario: Scenario
    window_s: float | None = None
    result_address: int | None = None
    noise: float = 0.0
    address: int = 0
    unit: str = ""  # its plant unit in the gateway config (a plant's loops: the plant's)


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
    plants: tuple[SimPlant, ...] = ()
    step_test: StepTest | None = None  # one loop held in manual, playing a step test

    @property
    def position_base(self) -> int:
        """The first register of the valve positions: after every loop's and plant loop's
        block (so no loop's OP/PV register moves); single loop ``k`` (config order) has its
        position, float32 % of valve span, at ``position_base + 2 k``."""
        ends = [lp.address + REGISTERS_PER_LOOP for lp in self.loops]
        ends += [p.address + REGISTERS_PER_LOOP * len(p.loops) for p in self.plants]
        return max(ends, default=0)

    def position_address(self, k: int) -> int:
        """The position register of single loop ``k`` (config order)."""
        return self.position_base + 2 * k

    def loop_names(self) -> list[str]:
        """Every loop served, in register order: the single loops, then the plants'."""
        return [lp.name for lp in self.loops] + [p.name(lp) for p in self.plants
                                                 for lp in p.loops]


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
    loops: list[SimLoop] = []
    names: set[str] = set()
    next_address = 0
    used: list[tuple[int, str]] = []
    # loops may be left out when plants are given
    singles = s.entries(top, "loops", "loop") if top.has("loops") or not top.has("plants") \
        else iter(())
    for _i, _name, sec in singles:
        lname = sec.req("name", s.string)
        sc_name = sec.req("scenario", s.choice(tuple(SCENARIOS)))
        noise = sec.opt("noise", s.number(non_negative=True), 0.0)
        params = sec.opt("params", s.mapping, {})
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
        loops.append(SimLoop(lname, sc, window_s=window, result_address=result_address,
                             noise=noise, address=address))
    plants = _parse_plants(top, names, used, next_address)
    step_test = _parse_step_test(top, {lp.name for lp in loops}, source, ts)
    used.sort()
    for (a0, n0), (a1, n1) in itertools.pairwise(used):
        if a1 < a0 + REGISTERS_PER_LOOP:
            problems.add(f"loop {n1}", "address", f"registers {a1}..{a1 + 3} overlap loop {n0}")
    top.done()
    if not problems.ok:
        raise ConfigError(problems.lines)
    return SimConfig(tuple(loops), listen, unit_id, ts, time_scale, seed, word_order,
                     protocol, opcua, plants, step_test)


def _parse_step_test(top: Section, loops: set[str], source: str, ts: Any
                     ) -> StepTest | None:
    """The ``step_test`` section (optional): a single loop, its start, hold and record."""
    if not top.has("step_test"):
        return None
    sec = top.sub("step_test", "step_test")
    loop = sec.req("loop", s.string)
    start = sec.opt("start_s", s.number(non_negative=True), 0.0)
    hold = sec.opt("hold_s", s.number(positive=True), None)
    record = sec.opt("record", s.string, None)
    sec.done()
    if loop is not MISSING and loop not in loops:
        sec.error("loop", f"no single loop {loop!r} (loops: {', '.join(sorted(loops))})")
        return None
    if hold not in (MISSING, None) and ts is not MISSING and hold < 5 * ts:
        sec.error("hold_s", f"must hold at least 5 samples (ts {ts:g} s)")
        return None
    if MISSING in (loop, start, hold, record):
        return None
    path = None
    if record is not None:
        base = Path(source).parent if Path(source).is_file() else Path.cwd()
        path = Path(record).expanduser()
        path = path if path.is_absolute() else base / path
    return StepTest(loop, start, hold, path)


def _parse_plants(top: Section, names: set[str], used: list[tuple[int, str]],
                  next_address: int) -> tuple[SimPlant, ...]:
    """The ``plants`` list (optional): each plant's loops take 4 registers each."""
    if not top.has("plants"):
        return ()
    out = []
    for _i, _name, sec in s.entries(top, "plants", "plant"):
        plant = sec.req("plant", s.choice(tuple(NAMED_PLANTS)))
        prefix = sec.opt("prefix", s.string, "")
        address = sec.opt("address", s.integer(0, 65536 - REGISTERS_PER_LOOP), next_address)
        window = sec.opt("window_s", s.number(positive=True), None)
        unit = sec.opt("unit", s.string, None)
        duration = sec.opt("duration_s", s.number(positive=True), DEFAULT_DURATION_S)
        sec.done()
        if MISSING in (plant, prefix, address, window, duration, unit):
            continue
        unit = unit or prefix.rstrip("._-/: ") or plant
        p = SimPlant(NAMED_PLANTS[plant], prefix, address, window, duration, unit)
        for k, lp in enumerate(p.loops):
            name = p.name(lp)
            if name in names:
                sec.error("prefix", f"loop name {name!r} is taken: set another prefix")
            names.add(name)
            used.append((address + REGISTERS_PER_LOOP * k, name))
        next_address = address + REGISTERS_PER_LOOP * len(p.loops)
        out.append(p)
    return tuple(out)


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
