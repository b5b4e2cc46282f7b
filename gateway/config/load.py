"""Gateway configuration: YAML → frozen dataclasses, validated at load without any network.

:func:`load_config` reads a file and returns a :class:`Config` or raises
:class:`~gateway.errors.ConfigError` listing every problem at once, each naming the file,
the section (``device plc1``, ``loop FIC101``, ``gateway``...) and the key.

Protocol-specific keys (a Modbus device's ``host``, a point's ``type``...) are parsed by the
protocol's plugin module (see :mod:`gateway.inputs`); the core keys are parsed here.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeGuard

import yaml

from ..errors import ConfigError
from ..inputs import protocol_names, protocol_plugin
from . import schema as s
from .schema import MISSING, Problems, Section

__all__ = [
    "RESULT_BLOCK_SIZE",
    "RESULT_LOOPS_PER_UNIT",
    "Config",
    "DeviceConfig",
    "GatewaySettings",
    "LoopConfig",
    "MetricsSettings",
    "PointConfig",
    "ResultServerSettings",
    "load_config",
    "parse_config",
]

RESULT_BLOCK_SIZE = 20
"""Registers per loop in the result server (offsets +0..+19, see docs/modbus-map.md)."""
RESULT_LOOPS_PER_UNIT = 65536 // RESULT_BLOCK_SIZE
"""Loops whose result blocks fit one unit id's 16-bit register space (3,276)."""
MAX_RESULT_UNIT_ID = 247

MIN_WINDOW_SAMPLES = 16
PROCESSES = ("self-regulating", "integrating")
WORD_ORDERS = ("big", "little")


@dataclasses.dataclass(frozen=True)
class GatewaySettings:
    analysis_interval_s: float = 300.0  # process seconds between analyses of a loop
    time_scale: float = 1.0  # process seconds per wall second (>1 only for simulation)
    state_file: str = "state/gateway.state"
    analysis_workers: int = 0  # worker processes; 0 = one per core less one (at least 1)
    persist_interval_s: float = 300.0  # wall seconds between state-file writes (and at exit)
    reconnect_max_s: float = 30.0  # wall seconds, cap of the jittered reconnect backoff


@dataclasses.dataclass(frozen=True)
class MetricsSettings:
    listen: tuple[str, int] = ("127.0.0.1", 9108)


@dataclasses.dataclass(frozen=True)
class ResultServerSettings:
    listen: tuple[str, int] = ("127.0.0.1", 5020)
    unit_id: int = 1
    word_order: str = "big"


@dataclasses.dataclass(frozen=True)
class DeviceConfig:
    """One device (one connection). ``options`` is the protocol plugin's own frozen
    dataclass (e.g. :class:`gateway.inputs.modbus.ModbusDeviceOptions`)."""

    name: str
    protocol: str
    poll_interval_s: float  # also the sample time Ts of its loops, in process seconds
    timeout_s: float
    options: Any


@dataclasses.dataclass(frozen=True)
class PointConfig:
    """One value of a loop: ``address`` is the protocol plugin's own point type (e.g.
    :class:`gateway.inputs.modbus.ModbusPoint`); engineering value = raw*scale + offset."""

    address: Any
    scale: float = 1.0
    offset: float = 0.0
    range: tuple[float, float] | None = None  # plausible engineering values; outside -> BAD


@dataclasses.dataclass(frozen=True)
class LoopConfig:
    name: str
    device: str
    op: PointConfig  # OP in % of valve span (after scale/offset)
    pv: PointConfig
    result_address: int
    process: str = "self-regulating"
    kp: float | None = None
    delay_s: float = 0.0
    window_s: float = 7200.0
    op_range: tuple[float, float] = (0.0, 100.0)
    # unit id of the result block; None: modbus_server.unit_id (load_config always fills
    # it in). Not in repr: like result_address it does not change what the loop's
    # assessment means (state.result_signature), and state files stay compatible.
    result_unit_id: int | None = dataclasses.field(default=None, repr=False)


@dataclasses.dataclass(frozen=True)
class Config:
    source: str
    devices: tuple[DeviceConfig, ...]
    loops: tuple[LoopConfig, ...]
    gateway: GatewaySettings = GatewaySettings()
    metrics: MetricsSettings = MetricsSettings()
    modbus_server: ResultServerSettings = ResultServerSettings()

    def device(self, name: str) -> DeviceConfig:
        for dev in self.devices:
            if dev.name == name:
                return dev
        raise KeyError(name)

    def loops_of(self, device: str) -> tuple[LoopConfig, ...]:
        return tuple(lp for lp in self.loops if lp.device == device)

    def window_samples(self, loop: LoopConfig) -> int:
        """Ring-buffer length of a loop: window_s / poll_interval_s samples."""
        return max(MIN_WINDOW_SAMPLES,
                   round(loop.window_s / self.device(loop.device).poll_interval_s))


def load_config(path: str | os.PathLike[str]) -> Config:
    """Read and validate a YAML config file; raise ConfigError listing every problem."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError([f"{source}: cannot read: {exc.strerror or exc}"]) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        detail = str(exc).replace("\n", " ")
        raise ConfigError([f"{source}: invalid YAML: {detail}"]) from None
    return parse_config(data, source)


def parse_config(data: Any, source: str = "<config>") -> Config:
    """Validate an already-parsed YAML document (a mapping)."""
    problems = Problems(source)
    top = Section(problems, "top level", data)
    if data is None or not top.valid:
        if data is None:
            problems.add("top level", None, "the file is empty")
        raise ConfigError(problems.lines)

    gateway = _parse_gateway(top.sub("gateway", "gateway"))
    metrics = _parse_metrics(top.sub("metrics", "metrics"))
    server = _parse_server(top.sub("modbus_server", "modbus_server"))

    devices: dict[str, DeviceConfig | None] = {}  # None: named but invalid
    protocols: dict[str, str] = {}  # device name -> protocol, also for invalid devices
    raw_devices = top.req("devices", _nonempty_list)
    for i, raw in enumerate(raw_devices if raw_devices is not MISSING else []):
        name = raw.get("name") if isinstance(raw, Mapping) else None
        where = f"device {name}" if isinstance(name, str) and name else f"devices[{i}]"
        sec = Section(problems, where, raw)
        if not sec.valid:
            continue
        dname = sec.req("name", s.string)
        protocol = sec.req("protocol", s.string)
        poll = sec.req("poll_interval_s", s.number(positive=True))
        timeout = sec.req("timeout_s", s.number(positive=True))
        options: Any = MISSING
        if dname is not MISSING and protocol is not MISSING:
            protocols.setdefault(dname, protocol)
        if protocol is not MISSING:
            plugin = protocol_plugin(protocol)
            if plugin is None:
                sec.error("protocol", f"unknown protocol {protocol!r} "
                          f"(known: {', '.join(protocol_names())})")
            else:
                options = plugin.parse_device(sec)
        sec.done()
        if dname is not MISSING and dname in devices:
            sec.error("name", f"duplicate device name {dname!r}")
            continue
        if MISSING in (dname, protocol, poll, timeout, options):
            devices.setdefault(dname if dname is not MISSING else f"#{i}", None)
            continue
        devices[dname] = DeviceConfig(dname, protocol, poll, timeout, options)

    loops: list[LoopConfig] = []
    # (loop, result unit id, result_address) of every loop that has both
    blocks: list[tuple[str, int, int]] = []
    names: set[str] = set()
    raw_loops = top.req("loops", _nonempty_list)
    for i, raw in enumerate(raw_loops if raw_loops is not MISSING else []):
        name = raw.get("name") if isinstance(raw, Mapping) else None
        where = f"loop {name}" if isinstance(name, str) and name else f"loops[{i}]"
        sec = Section(problems, where, raw)
        if not sec.valid:
            continue
        loop = _parse_loop(sec, devices, protocols, server.unit_id)
        sec.done()
        address = sec.raw.get("result_address")
        unit = sec.raw.get("result_unit_id", server.unit_id)
        if isinstance(name, str) and _is_int(address) and _is_int(unit) \
                and (unit == server.unit_id or 1 <= unit <= MAX_RESULT_UNIT_ID):
            blocks.append((name, unit, address))
        if isinstance(name, str):
            if name in names:
                sec.error("name", f"duplicate loop name {name!r}")
                continue
            names.add(name)
        if loop is not None:
            loops.append(loop)
    top.done()
    _check_result_blocks(problems, blocks, server.unit_id)
    if not problems.ok:
        raise ConfigError(problems.lines)
    return Config(source, tuple(d for d in devices.values() if d is not None), tuple(loops),
                  gateway, metrics, server)


def _is_int(value: Any) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


def _nonempty_list(value: Any) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise TypeError("must be a non-empty list")
    return value


def _parse_gateway(sec: Section) -> GatewaySettings:
    d = GatewaySettings()
    out = GatewaySettings(
        analysis_interval_s=sec.opt("analysis_interval_s", s.number(positive=True),
                                    d.analysis_interval_s),
        time_scale=sec.opt("time_scale", s.number(positive=True), d.time_scale),
        state_file=sec.opt("state_file", s.string, d.state_file),
        analysis_workers=sec.opt("analysis_workers", s.integer(0, 256), d.analysis_workers),
        persist_interval_s=sec.opt("persist_interval_s", s.number(positive=True),
                                   d.persist_interval_s),
        reconnect_max_s=sec.opt("reconnect_max_s", s.number(positive=True), d.reconnect_max_s),
    )
    sec.done()
    return out


def _parse_metrics(sec: Section) -> MetricsSettings:
    out = MetricsSettings(listen=sec.opt("listen", s.listen_address, MetricsSettings.listen))
    sec.done()
    return out


def _parse_server(sec: Section) -> ResultServerSettings:
    d = ResultServerSettings()
    out = ResultServerSettings(
        listen=sec.opt("listen", s.listen_address, d.listen),
        unit_id=sec.opt("unit_id", s.integer(0, 247), d.unit_id),
        word_order=sec.opt("word_order", s.choice(WORD_ORDERS), d.word_order),
    )
    sec.done()
    return out


def _parse_point(sec: Section, device: DeviceConfig | None,
                 protocol: str | None) -> PointConfig | None:
    """A loop's op/pv point; with ``device`` None (the device itself is invalid) the keys
    are still checked against ``protocol`` if known, so every problem is reported."""
    scale = sec.opt("scale", s.number(), 1.0)
    offset = sec.opt("offset", s.number(), 0.0)
    valid = sec.opt("range", s.number_pair, None)
    if scale == 0.0:
        sec.error("scale", "must not be 0")
        scale = MISSING
    address: Any = MISSING
    plugin = protocol_plugin(device.protocol if device is not None else protocol or "")
    if plugin is not None:
        address = plugin.parse_point(sec, device.options if device is not None else None)
    else:  # unknown device or protocol: the device's own error says it all
        for key in sec.raw:
            sec.raw_value(key)
    sec.done()
    if MISSING in (scale, offset, address, valid):
        return None
    return PointConfig(address, scale, offset, valid)


def _parse_loop(sec: Section, devices: Mapping[str, DeviceConfig | None],
                protocols: Mapping[str, str], default_unit: Any) -> LoopConfig | None:
    name = sec.req("name", s.string)
    device_name = sec.req("device", s.string)
    device: DeviceConfig | None = None
    if device_name is not MISSING:
        if device_name not in devices:
            known = ", ".join(k for k in devices if not k.startswith("#")) or "none"
            sec.error("device", f"unknown device {device_name!r} (devices: {known})")
        else:
            device = devices[device_name]
    points: dict[str, PointConfig | None] = {}
    for role in ("op", "pv"):
        if not sec.has(role):
            sec.req(role, dict)  # records "missing required key"
            points[role] = None
            continue
        psec = sec.sub(role)
        points[role] = (_parse_point(psec, device, protocols.get(device_name))
                        if psec.valid else None)
    process = sec.opt("process", s.choice(PROCESSES), "self-regulating")
    kp = sec.opt("kp", _kp, None)
    delay = sec.opt("delay_s", s.number(non_negative=True), 0.0)
    window = sec.opt("window_s", s.number(positive=True), 7200.0)
    op_range = sec.opt("op_range", s.number_pair, (0.0, 100.0))
    result_address = sec.req("result_address",
                             s.integer(0, 65536 - RESULT_BLOCK_SIZE))
    result_unit_id = sec.opt("result_unit_id", s.integer(1, MAX_RESULT_UNIT_ID), default_unit)
    if device is not None and window is not MISSING \
            and window / device.poll_interval_s < MIN_WINDOW_SAMPLES:
        sec.error("window_s", f"must hold at least {MIN_WINDOW_SAMPLES} samples of device "
                  f"{device.name} (poll_interval_s {device.poll_interval_s:g})")
        window = MISSING
    values = (name, device_name, process, kp, delay, window, op_range, result_address,
              result_unit_id)
    if MISSING in values or device is None or None in points.values():
        return None
    op, pv = points["op"], points["pv"]
    assert op is not None
    assert pv is not None
    return LoopConfig(name=name, device=device_name, op=op, pv=pv,
                      result_address=result_address, process=process, kp=kp,
                      delay_s=delay, window_s=window, op_range=op_range,
                      result_unit_id=result_unit_id)


def _kp(value: Any) -> float | None:
    if value is None:
        return None
    out = s.number()(value)
    if out == 0.0:
        raise ValueError("must not be 0")
    return out


def _check_result_blocks(problems: Problems, blocks: list[tuple[str, int, int]],
                         default_unit: Any) -> None:
    """Within each result unit id, a loop's 20-register block must not overlap another's
    (reported once per pair of neighbours in address order); the same address on two unit
    ids is fine."""
    ordered = sorted(blocks, key=lambda b: (b[1], b[2]))
    for (pname, punit, pa), (name, unit, a) in itertools.pairwise(ordered):
        if unit == punit and a < pa + RESULT_BLOCK_SIZE:
            n = RESULT_BLOCK_SIZE - 1
            where = "" if unit == default_unit else f" on result unit id {unit}"
            problems.add(f"loop {name}", "result_address",
                         f"block {a}..{a + n} overlaps loop {pname} ({pa}..{pa + n}){where}")
