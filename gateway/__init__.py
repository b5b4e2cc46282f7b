"""The stiction gateway daemon: polls PLCs, analyses loop windows, publishes results.

The package is laid out one folder per concern (docs/architecture.md): ``config`` (YAML ->
frozen dataclasses, the one validator, the plugin registry), ``core`` (the rules, no IO),
``inputs`` (a :class:`Source` per protocol), ``outputs`` (a :class:`Sink` per output),
``wire`` (what inputs, outputs and the simulated PLC share), ``runtime`` (the asyncio
shell). The public names below are imported on first use, so ``import gateway`` stays cheap.

=====================  ====================================================================
:class:`Gateway`       one running gateway (async context manager); ``reload(path)``
:func:`run`            ``stiction-gateway run``: serve until SIGTERM, reload on SIGHUP
:func:`serve`          run a gateway until an event is set (embedding, tests)
:func:`load_config`    read and validate a YAML file -> :class:`Config`
:func:`parse_config`   validate an already-parsed document -> :class:`Config`
:class:`Config`        the whole configuration (frozen)
:class:`GatewayError`  root of the gateway's exceptions: :class:`ConfigError` (every
                       problem of a config file), :class:`DeviceError` (a device failed)
:class:`Source`        what an input implements: ``connect``, ``read``, ``close``
:class:`ReadResult`    one read: raw values and qualities, one per point
:class:`PointSpec`     one point of a device (loop, role, address, scale, offset, range)
:class:`Quality`       quality of a sample (GOOD, UNCERTAIN, BAD, NO_COMM, MISSING)
:class:`Sink`          what an output implements: ``start``, ``bind``, ``stop``
:class:`Binding`       what sinks serve: config, loop groups, result store, clock
:class:`ResultStore`   the latest assessment, sample and stale flag of every loop
:class:`LoopResult`    one loop's latest assessment with its sequence number and time
=====================  ====================================================================
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

__all__ = [
    "Binding",
    "Config",
    "ConfigError",
    "DeviceError",
    "Gateway",
    "GatewayError",
    "LoopResult",
    "PointSpec",
    "Quality",
    "ReadResult",
    "ResultStore",
    "Sink",
    "Source",
    "__version__",
    "load_config",
    "parse_config",
    "run",
    "serve",
]

_HOMES = {
    "Binding": "gateway.outputs.base",
    "Config": "gateway.config",
    "ConfigError": "gateway.errors",
    "DeviceError": "gateway.errors",
    "Gateway": "gateway.runtime.gateway",
    "GatewayError": "gateway.errors",
    "LoopResult": "gateway.core.store",
    "PointSpec": "gateway.core.points",
    "Quality": "gateway.core.points",
    "ReadResult": "gateway.inputs.base",
    "ResultStore": "gateway.core.store",
    "Sink": "gateway.outputs.base",
    "Source": "gateway.inputs.base",
    "load_config": "gateway.config",
    "parse_config": "gateway.config",
    "run": "gateway.runtime.service",
    "serve": "gateway.runtime.service",
}

if TYPE_CHECKING:
    from .config import Config, load_config, parse_config
    from .core.points import PointSpec, Quality
    from .core.store import LoopResult, ResultStore
    from .errors import ConfigError, DeviceError, GatewayError
    from .inputs.base import ReadResult, Source
    from .outputs.base import Binding, Sink
    from .runtime.gateway import Gateway
    from .runtime.service import run, serve


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'gateway' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
