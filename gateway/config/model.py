"""The gateway configuration as frozen dataclasses (what :mod:`gateway.config.load` returns).

Every value has its documented default (docs/configuration.md); protocol-specific device
and point settings are the protocol plugin's own frozen dataclasses (``options`` and
``address``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

__all__ = [
    "DEFAULT_POLL_INTERVAL_S",
    "DEFAULT_TIMEOUT_S",
    "MIN_WINDOW_SAMPLES",
    "PROCESSES",
    "WORD_ORDERS",
    "AnalysisSettings",
    "Config",
    "DeviceConfig",
    "GatewaySettings",
    "HysteresisSettings",
    "LoopConfig",
    "MetricsSettings",
    "PlantSettings",
    "PointConfig",
    "ResultServerSettings",
    "default_timeout",
]

MIN_WINDOW_SAMPLES = 16
DEFAULT_POLL_INTERVAL_S = 1.0  # a device's poll_interval_s when the config leaves it out
DEFAULT_TIMEOUT_S = 1.0  # ... and its timeout_s, never more than its poll interval
PROCESSES = ("self-regulating", "integrating")
WORD_ORDERS = ("big", "little")


def default_timeout(poll_interval_s: float) -> float:
    """A device's ``timeout_s`` when the config leaves it out: 1 s, or the poll interval
    if that is shorter (a poll must end before the next one is due)."""
    return min(DEFAULT_TIMEOUT_S, poll_interval_s)


@dataclasses.dataclass(frozen=True)
class GatewaySettings:
    analysis_interval_s: float = 300.0  # process seconds between analyses of a loop
    time_scale: float = 1.0  # process seconds per wall second (>1 only for simulation)
    state_file: str = "state/gateway.state"
    analysis_workers: int = 0  # worker processes; 0 = one per core less one (at least 1)
    persist_interval_s: float = 300.0  # wall seconds between state-file writes (and at exit)
    reconnect_max_s: float = 30.0  # wall seconds, cap of the jittered reconnect backoff
    # fleet identity (docs/fleet.md): the `site` and `area` labels of stiction_build_info;
    # the site's Prometheus puts the same labels on every series (external_labels)
    site: str | None = None
    area: str | None = None
    # MiB the loop windows may take (with the state file's copy); None: half the machine's
    # memory (or of the service's memory limit), see gateway.config.checks
    memory_limit_mb: float | None = None


@dataclasses.dataclass(frozen=True)
class MetricsSettings:
    listen: tuple[str, int] = ("127.0.0.1", 9108)
    max_connections: int = 16  # at once; beyond, a newcomer closes the costliest one
    idle_timeout_s: float = 30.0  # a connection that sends nothing this long is closed


@dataclasses.dataclass(frozen=True)
class ResultServerSettings:
    listen: tuple[str, int] = ("127.0.0.1", 5020)
    unit_id: int = 1
    word_order: str = "big"
    max_connections: int = 64
    idle_timeout_s: float = 60.0
    # what read device identification (FC 43/14) answers: (object name, text) pairs of
    # gateway.wire.registers.IDENTIFICATION_OBJECTS; empty: FC 43 is refused
    identification: tuple[tuple[str, str], ...] = ()
    # registers per loop: 20 (the block every SCADA map made before reads) or 32 (the
    # extended block: +20.. what was added since, gateway.wire.results.EXTENSION)
    block_registers: int = 20


@dataclasses.dataclass(frozen=True)
class PlantSettings:
    """The plant-wide step after each analysis round (docs/configuration.md, ``plant``)."""

    enabled: bool = True  # run stiction.plant over the loops that share a poll interval
    # samples per signal the plant analysis sees: longer windows are averaged down (bounds
    # its memory and time; the per-loop analysis always sees the whole window)
    max_samples: int = 1024
    # rounds a changed plant view (a group appearing or ending, a source, a loop's role)
    # must hold before it is published (gateway.core.planthold); 1: at once
    hold_rounds: int = 3


@dataclasses.dataclass(frozen=True)
class HysteresisSettings:
    """``verdict_hysteresis``: when a published verdict may change (docs/configuration.md,
    :mod:`gateway.core.hysteresis`)."""

    rounds: int = 5  # analysis rounds a new verdict must hold (1: every round's is published)
    margin: float = 0.5  # ... or the change of confidence that publishes it at once (0-1)
    band: float = 0.02  # a confidence this near a threshold neither counts nor resets (0-0.5)


@dataclasses.dataclass(frozen=True)
class AnalysisSettings:
    """``analysis``: what the gateway makes of the analysis (docs/configuration.md)."""

    # fit the site's own calibration of the confidence on the findings file, once it holds
    # findings of both kinds (stiction.ranking.calibration; runtime/crewlist.py)
    site_calibration: bool = True
    # findings of each kind (sticky, not sticky) before the site's calibration is fitted
    site_calibration_min_each: int = 5
    # call each loop at the share of sticky valves the loops' own windows imply (label-shift
    # EM over the shape network's readings: core/siteshare.py); false: each loop alone
    site_adaptation: bool = True


@dataclasses.dataclass(frozen=True)
class DeviceConfig:
    """One device (one connection). ``options`` is the protocol plugin's own frozen
    dataclass (e.g. :class:`gateway.inputs.modbus.config.ModbusDeviceOptions`)."""

    name: str
    protocol: str
    poll_interval_s: float  # also the sample time Ts of its loops, in process seconds
    timeout_s: float
    options: Any


@dataclasses.dataclass(frozen=True)
class PointConfig:
    """One value of a loop: ``address`` is the protocol plugin's own point type (e.g.
    `gateway.inputs.modbus.config.ModbusPoint`); engineering value = raw*scale + offset."""

    address: Any
    scale: float = 1.0
    offset: float = 0.0
    range: tuple[float, float] | None = None  # plausible engineering values; outside -> BAD
    # may read the same registers as another point that says so too (a split-range PV);
    # not in repr: it changes nothing of the samples (window signatures stay)
    shared: bool = dataclasses.field(default=False, repr=False)


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
    # where the loop is listed, for messages about it: "loops.csv: line 4" for a tag-list
    # row, "" for the YAML. Neither in repr nor compared: moving a row keeps its window.
    origin: str = dataclasses.field(default="", repr=False, compare=False)
    # the plant unit (area) it belongs to: the plant view groups loops of one unit only
    # ("": no unit). Not in repr: it changes neither the window nor the assessment.
    unit: str = dataclasses.field(default="", repr=False)
    # the valve's position as its positioner reports it, in OP units (% of span), optional:
    # where it is read, stiction is measured from the valve's travel. Not in repr: a loop
    # without one keeps the signatures (and state files) it had before the key existed;
    # core.windows.loop_signature adds it where it is set.
    position: PointConfig | None = dataclasses.field(default=None, repr=False)
    # the plant's weight of the loop in the list worst first (core/ranking.py): the
    # suspicion is multiplied by it. Not in repr: it changes neither the window nor the
    # assessment (signatures and state files stay)
    priority: float = dataclasses.field(default=1.0, repr=False)

    @property
    def points(self) -> tuple[tuple[str, PointConfig], ...]:
        """``(role, point)`` of the loop's points, in the order its device reads them: OP,
        PV, and the position where the loop has one."""
        both = (("op", self.op), ("pv", self.pv))
        return both if self.position is None else (*both, ("position", self.position))


@dataclasses.dataclass(frozen=True)
class Config:
    source: str
    devices: tuple[DeviceConfig, ...]
    loops: tuple[LoopConfig, ...]
    gateway: GatewaySettings = GatewaySettings()
    metrics: MetricsSettings = MetricsSettings()
    modbus_server: ResultServerSettings = ResultServerSettings()
    # loops whose result_address the loader assigned (config/addresses.py), in config order
    assigned: tuple[str, ...] = ()
    plant: PlantSettings = PlantSettings()
    hysteresis: HysteresisSettings = HysteresisSettings()
    # the engineer's findings file (`findings:`, relative paths resolved against the
    # config's folder); None: none. Read at start and on SIGHUP, never by load_config: a
    # bad findings file never makes the config invalid (gateway.config.findings)
    findings: str | None = None
    analysis: AnalysisSettings = AnalysisSettings()

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
