"""Gateway configuration: YAML → frozen dataclasses, validated at load without any network.

:func:`load_config` reads a file and returns a :class:`Config` or raises
:class:`~gateway.errors.ConfigError` listing every problem at once, each naming the file,
the section (``device plc1``, ``loop FIC101``, ``gateway``...) and the key.

Protocol-specific keys (a Modbus device's ``host``, a point's ``type``...) are parsed by the
protocol's plugin module, found by name in :mod:`gateway.config.plugins`; the core keys are
parsed here, all with the one validator (:mod:`gateway.config.schema`). Loops may also come
from tag lists (``loops_csv``, :mod:`gateway.config.tags`); loops without ``result_address``
get one by the rule of :mod:`gateway.config.addresses`.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Mapping
from typing import Any, TypeGuard, TypeVar

from ..errors import ConfigError
from ..wire.results import BLOCK_SIZES, MAX_RESULT_UNIT_ID, overlapping_blocks
from . import schema as s
from .addresses import assign_result_addresses
from .checks import check_config, identification
from .findings import findings_path
from .limits import read_document
from .model import (
    DEFAULT_POLL_INTERVAL_S,
    MIN_WINDOW_SAMPLES,
    PROCESSES,
    WORD_ORDERS,
    AnalysisSettings,
    Config,
    DeviceConfig,
    GatewaySettings,
    HysteresisSettings,
    LoopConfig,
    MetricsSettings,
    PlantSettings,
    PointConfig,
    ResultServerSettings,
    default_timeout,
)
from .overlaps import check_overlaps
from .plugins import input_names, input_plugin
from .schema import MISSING, Problems, Section
from .tags import tag_entries, tag_tables

__all__ = ["load_config", "parse_config"]

T = TypeVar("T")


def load_config(path: str | os.PathLike[str]) -> Config:
    """Read and validate a YAML config file; raise ConfigError listing every problem."""
    source = str(path)
    return parse_config(read_document(path), source)  # within limits.py's bounds


def parse_config(data: Any, source: str = "<config>", *, one_gateway: bool = True) -> Config:
    """Validate an already-parsed YAML document (a mapping).

    ``one_gateway=False`` validates the loops of several gateways at once (a tag list before
    ``shard`` splits it): every key and row is checked, but not what belongs to each gateway
    alone (its result blocks fitting and not overlapping, its memory and listeners); the
    split checks those per gateway."""
    problems = Problems(source)
    top = Section(problems, "top level", data)
    if data is None or not top.valid:
        if data is None:
            problems.add("top level", None, "the file is empty")
        raise ConfigError(problems.lines)

    gateway = _settings(top.sub("gateway", "gateway"), GatewaySettings, GATEWAY_KEYS)
    metrics = _settings(top.sub("metrics", "metrics"), MetricsSettings, METRICS_KEYS)
    server = _settings(top.sub("modbus_server", "modbus_server"), ResultServerSettings,
                       SERVER_KEYS)
    plant = _settings(top.sub("plant", "plant"), PlantSettings, PLANT_KEYS)
    hysteresis = _settings(top.sub("verdict_hysteresis", "verdict_hysteresis"),
                           HysteresisSettings, HYSTERESIS_KEYS)
    analysis = _settings(top.sub("analysis", "analysis"), AnalysisSettings, ANALYSIS_KEYS)

    devices: dict[str, DeviceConfig | None] = {}  # None: named but invalid
    protocols: dict[str, str] = {}  # device name -> protocol, also for invalid devices
    for i, _name, sec in s.entries(top, "devices", "device"):
        dname = sec.req("name", s.string)
        protocol = sec.req("protocol", s.string)
        poll = sec.opt("poll_interval_s", s.number(positive=True), DEFAULT_POLL_INTERVAL_S)
        timeout = sec.opt("timeout_s", s.number(positive=True), None)
        if timeout is None:
            timeout = default_timeout(poll if poll is not MISSING else DEFAULT_POLL_INTERVAL_S)
        options: Any = MISSING
        if dname is not MISSING and protocol is not MISSING:
            protocols.setdefault(dname, protocol)
        if protocol is not MISSING:
            plugin = input_plugin(protocol)
            if plugin is None:
                sec.error("protocol", f"unknown protocol {protocol!r} "
                          f"(known: {', '.join(input_names())})")
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
    sections: dict[str, Section] = {}  # loop name -> its section, for later problems
    tables = tag_tables(top)  # loops_csv: loops from tag lists, after those of `loops`
    findings = top.opt("findings", s.string, None)  # the file is read by run, not here
    listed = s.entries(top, "loops", "loop") if top.has("loops") or not tables else ()
    for _i, name, sec in itertools.chain(listed, tag_entries(problems, tables, protocols)):
        loop = _parse_loop(sec, devices, protocols, server.unit_id, server.block_registers)
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
            sections[name] = sec
        if loop is not None:
            loops.append(loop)
    top.done()
    check_overlaps(sections, [d for d in devices.values() if d is not None], loops)
    assigned: list[str] = []
    if one_gateway:  # several gateways: each assigns its own blocks
        loops, assigned, full = assign_result_addresses(loops, blocks, server.block_registers)
        for name, message in full.items():
            sections[name].error("result_address", message)
        _check_result_blocks(problems, sections, blocks, server.unit_id,
                             server.block_registers)
    if not problems.ok:
        raise ConfigError(problems.lines)
    config = Config(source, tuple(d for d in devices.values() if d is not None),
                    tuple(loops), gateway, metrics, server, assigned=tuple(assigned),
                    plant=plant, hysteresis=hysteresis, analysis=analysis,
                    findings=None if findings in (None, MISSING)
                    else str(findings_path(source, findings)))
    if one_gateway:
        check_config(problems, config)  # what run would refuse or crash on (checks.py)
    if not problems.ok:
        raise ConfigError(problems.lines)
    return config


def _is_int(value: Any) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


GATEWAY_KEYS: dict[str, Callable[[Any], Any]] = {
    "analysis_interval_s": s.number(positive=True),
    "time_scale": s.number(positive=True),
    "state_file": s.string,
    "analysis_workers": s.integer(0, 256),
    "persist_interval_s": s.number(positive=True),
    "reconnect_max_s": s.number(positive=True),
    "site": s.label_value,
    "area": s.label_value,
    "memory_limit_mb": s.number(positive=True),
}
METRICS_KEYS: dict[str, Callable[[Any], Any]] = {
    "listen": s.listen_address,
    "max_connections": s.integer(1, 10000),
    "idle_timeout_s": s.number(positive=True),
}
PLANT_KEYS: dict[str, Callable[[Any], Any]] = {
    "enabled": s.boolean,
    "max_samples": s.integer(64, 65536),
    "hold_rounds": s.integer(1, 1000),
}
HYSTERESIS_KEYS: dict[str, Callable[[Any], Any]] = {
    "rounds": s.integer(1, 1000),
    "margin": s.number(non_negative=True, at_most=1.0),
    "band": s.number(non_negative=True, at_most=0.5),
}
ANALYSIS_KEYS: dict[str, Callable[[Any], Any]] = {
    "site_calibration": s.boolean,
    "site_calibration_min_each": s.integer(2, 1000),
    "site_adaptation": s.boolean,
}


def _block_registers(value: Any) -> int:
    """``modbus_server.block_registers``: 20 or 32."""
    if isinstance(value, bool) or value not in BLOCK_SIZES:
        raise ValueError(f"must be {' or '.join(map(str, BLOCK_SIZES))} (registers per "
                         "loop: 32 is the extended block, docs/modbus-map.md)")
    return int(value)


SERVER_KEYS: dict[str, Callable[[Any], Any]] = {
    "listen": s.listen_address,
    "unit_id": s.integer(0, 247),
    "word_order": s.choice(WORD_ORDERS),
    "max_connections": s.integer(1, 10000),
    "idle_timeout_s": s.number(positive=True),
    "identification": identification,
    "block_registers": _block_registers,
}


def _settings(sec: Section, cls: Callable[..., T], keys: Mapping[str, Callable[[Any], Any]]
              ) -> T:
    """A settings section: each key of ``keys`` read with its converter, defaulting to the
    dataclass ``cls``'s own default."""
    defaults = cls()
    out = cls(**{key: sec.opt(key, conv, getattr(defaults, key)) for key, conv in keys.items()})
    sec.done()
    return out


def _parse_point(sec: Section, device: DeviceConfig | None,
                 protocol: str | None) -> PointConfig | None:
    """A loop's op/pv/position point; with ``device`` None (the device itself is invalid) the keys
    are still checked against ``protocol`` if known, so every problem is reported."""
    scale = sec.opt("scale", s.number(), 1.0)
    offset = sec.opt("offset", s.number(), 0.0)
    valid = sec.opt("range", s.number_pair, None)
    shared = sec.opt("shared", s.flag, False)
    if scale == 0.0:
        sec.error("scale", "must not be 0")
        scale = MISSING
    address: Any = MISSING
    plugin = input_plugin(device.protocol if device is not None else protocol or "")
    if plugin is not None:
        address = plugin.parse_point(sec, device.options if device is not None else None)
    else:  # unknown device or protocol: the device's own error says it all
        for key in sec.raw:
            sec.raw_value(key)
    sec.done()
    if MISSING in (scale, offset, address, valid, shared):
        return None
    return PointConfig(address, scale, offset, valid, shared)


def _parse_loop(sec: Section, devices: Mapping[str, DeviceConfig | None],
                protocols: Mapping[str, str], default_unit: Any,
                block: int) -> LoopConfig | None:
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
    position: PointConfig | None = None
    if sec.has("position"):
        psec = sec.sub("position")
        position = (_parse_point(psec, device, protocols.get(device_name))
                    if psec.valid else None)
        if position is None:
            points["position"] = None  # invalid: the loop is not built
    process = sec.opt("process", s.choice(PROCESSES), "self-regulating")
    kp = sec.opt("kp", _kp, None)
    delay = sec.opt("delay_s", s.number(non_negative=True), 0.0)
    window = sec.opt("window_s", s.number(positive=True), 7200.0)
    op_range = sec.opt("op_range", s.number_pair, (0.0, 100.0))
    result_address = sec.opt("result_address", s.integer(0, 65536 - block),
                             None)  # None: assigned once every loop is read
    result_unit_id = sec.opt("result_unit_id", s.integer(1, MAX_RESULT_UNIT_ID), default_unit)
    unit = sec.opt("unit", _unit, "")
    priority = sec.opt("priority", s.number(positive=True, at_most=1e6), 1.0)
    if device is not None and window is not MISSING \
            and window / device.poll_interval_s < MIN_WINDOW_SAMPLES:
        sec.error("window_s", f"must hold at least {MIN_WINDOW_SAMPLES} samples of device "
                  f"{device.name} (poll_interval_s {device.poll_interval_s:g})")
        window = MISSING
    values = (name, device_name, process, kp, delay, window, op_range, result_address,
              result_unit_id, unit, priority)
    if MISSING in values or device is None or None in points.values():
        return None
    op, pv = points["op"], points["pv"]
    assert op is not None
    assert pv is not None
    return LoopConfig(name=name, device=device_name, op=op, pv=pv,
                      result_address=result_address, process=process, kp=kp,
                      delay_s=delay, window_s=window, op_range=op_range,
                      result_unit_id=result_unit_id, origin=sec.origin, unit=unit,
                      position=position, priority=priority)


def _unit(value: Any) -> str:
    """A plant unit's name: text (a number in a tag list is read as its text), 1-64
    characters."""
    if isinstance(value, bool) or not isinstance(value, str | int):
        raise ValueError("must be a name")
    text = str(value).strip()
    if not 1 <= len(text) <= 64:
        raise ValueError("must be 1-64 characters")
    return text


def _kp(value: Any) -> float | None:
    if value is None:
        return None
    out = s.number()(value)
    if out == 0.0:
        raise ValueError("must not be 0")
    return out


def _check_result_blocks(problems: Problems, sections: Mapping[str, Section],
                         blocks: list[tuple[str, int, int]], default_unit: Any,
                         size: int) -> None:
    """Within each result unit id, a loop's block (``size`` registers) must not overlap
    another's (reported once per pair of neighbours in address order); the same address on
    two unit ids is fine."""
    n = size - 1
    for name, unit, a, other, oa in overlapping_blocks(blocks, size):
        where = "" if unit == default_unit else f" on result unit id {unit}"
        message = f"block {a}..{a + n} overlaps loop {other} ({oa}..{oa + n}){where}"
        if name in sections:
            sections[name].error("result_address", message)
        else:
            problems.add(f"loop {name}", "result_address", message)
