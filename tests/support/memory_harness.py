"""A gateway runtime driven by hand, with no sockets, no tasks and a fake clock.

``Harness(config)`` builds the runtime of a config whose devices use ``protocol: memory``
(or any sources ``make_source`` returns), with the pollers' clocks under the test's control.
:meth:`Harness.tick` polls every device once and moves the clock on by one poll period;
:meth:`Harness.analyse` runs one analysis round inline (the function a worker would run);
:meth:`Harness.registers` is a unit id's result-register image and :meth:`Harness.metric`
a sample of the Prometheus registry, both as the outputs would publish them.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import NDArray
from prometheus_client import CollectorRegistry

from gateway.config import Config
from gateway.core.jobs import analyze_batch, batches
from gateway.inputs.memory import MemorySource
from gateway.outputs.modbus_server import ResultServer
from gateway.outputs.prometheus import GatewayMetrics, StoreCollector
from gateway.runtime.poller import Clocks, DevicePoller
from gateway.runtime.reload import Runtime, build_runtime

WALL0 = 1_700_000_000.0
FAKE = "gateway_fake_analyze:analyze"


@dataclasses.dataclass
class FakeTime:
    mono: float = 0.0
    wall: float = WALL0

    def clocks(self) -> Clocks:
        return Clocks(mono=lambda: self.mono, wall=lambda: self.wall, perf=lambda: self.mono)

    def advance(self, seconds: float) -> None:
        self.mono += seconds
        self.wall += seconds


class Harness:
    def __init__(self, config: Config, *, old: Harness | None = None,
                 time: FakeTime | None = None, **build: Any) -> None:
        self.time = time or (old.time if old is not None else FakeTime())
        self.registry = CollectorRegistry()
        self.metrics = GatewayMetrics(self.registry)
        self.runtime: Runtime = build_runtime(
            config, old.runtime if old is not None else None, wall=self.time.wall,
            metrics=self.metrics, clocks=self.time.clocks(), **build)
        self.registry.register(StoreCollector(self.runtime.store))
        for dev in config.devices:
            self.metrics.add_device(dev.name)
        self.results = ResultServer(config.modbus_server, config.loops, self.runtime.store)
        self.config: Config = self.runtime.config
        self.store = self.runtime.store

    def poller(self, device: str) -> DevicePoller:
        return next(p for p in self.runtime.pollers if p.device.name == device)

    def source(self, device: str) -> MemorySource:
        src = self.poller(device).source
        assert isinstance(src, MemorySource)
        return src

    async def tick(self, n: int = 1, period: float | None = None) -> None:
        """Poll every device ``n`` times, the clock moving on ``period`` (default: the
        first device's poll period) after each round."""
        step = period if period is not None else self.runtime.pollers[0].period
        for _ in range(n):
            for p in self.runtime.pollers:
                await p.tick()
            self.time.advance(step)

    def analyse(self, path: str = FAKE) -> int:
        """One analysis round, inline; the results are stamped with the fake wall time."""
        done = 0
        for batch in batches(self.runtime.groups, 64):
            for index, assessment, fill, samples, _dur, _swing in analyze_batch(path, batch):
                self.store.set_result(index, assessment, t=self.time.wall, window_fill=fill,
                                      samples=samples)
                done += 1
        return done

    def registers(self, unit: int | None = None) -> NDArray[np.uint16]:
        return self.results.images[unit if unit is not None else
                                   self.config.modbus_server.unit_id]

    def block(self, loop: str) -> NDArray[np.uint16]:
        lc = self.config.loops[self.store.index[loop]]
        size = self.config.modbus_server.block_registers
        return self.registers(self.results.unit_of(lc))[lc.result_address:
                                                         lc.result_address + size]

    def metric(self, name: str, **labels: str) -> float | None:
        return self.registry.get_sample_value(name, labels)

    def window(self, loop: str) -> tuple[Any, Any, Any, Any]:
        """(t, op, pv, quality) of one loop's window, oldest first."""
        for g in self.runtime.groups:
            if loop in g.loops:
                t, op, pv, q = g.bank.series([g.loops.index(loop)])
                return t, op[0], pv[0], q[0]
        raise KeyError(loop)


def mloop(name: str, device: str, column: int, result_address: int, *,
          window_s: float = 10.0, **extra: Any) -> dict[str, Any]:
    """A loop reading OP from ``column`` and PV from ``column + 1`` of a memory device."""
    return {"name": name, "device": device, "op": {"column": column},
            "pv": {"column": column + 1}, "window_s": window_s,
            "result_address": result_address, **extra}


def mconfig(devices: list[dict[str, Any]], loops: list[dict[str, Any]], *,
            plant: dict[str, Any] | None = None, **gateway: Any) -> dict[str, Any]:
    """A raw config: memory devices, servers on free loopback ports, no analysis unless
    asked, a short reconnect cap. No plant-wide step unless ``plant`` asks: these tests run
    the analysis in a thread of the test's process (the gateway: in worker processes),
    where the plant step's fits would take the polls' interpreter."""
    return {"gateway": {"analysis_interval_s": 1e6, "analysis_workers": 1,
                        "reconnect_max_s": 0.5, **gateway},
            "metrics": {"listen": "127.0.0.1:0"},
            "modbus_server": {"listen": "127.0.0.1:0", "unit_id": 1},
            "plant": {"enabled": False} if plant is None else plant,
            "devices": devices, "loops": loops}


def wiggle(n: int, width: int, k0: int = 0) -> list[list[float]]:
    """``n`` rows of ``width`` columns: OP swinging around 50, PV around 20."""
    return [[round(float(50.0 + 10.0 * np.sin((k + c) / 5.0)), 4) if c % 2 == 0
             else round(float(20.0 + np.cos((k + c) / 7.0)), 4) for c in range(width)]
            for k in range(k0, k0 + n)]
