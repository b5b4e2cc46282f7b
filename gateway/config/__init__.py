"""Configuration: YAML -> frozen dataclasses, validated at load without any network.

:func:`load_config` / :func:`parse_config` (in :mod:`.load`) return a :class:`Config` (the
dataclasses of :mod:`.model`) or raise :class:`~gateway.errors.ConfigError` listing every
problem; :mod:`.schema` is the one validator every section and plugin reads keys with;
:mod:`.plugins` maps protocol and output names to their modules.
"""

from .load import load_config, parse_config
from .model import (
    Config,
    DeviceConfig,
    GatewaySettings,
    LoopConfig,
    MetricsSettings,
    PointConfig,
    ResultServerSettings,
)

__all__ = [
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
