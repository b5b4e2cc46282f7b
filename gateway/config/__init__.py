"""Configuration: YAML -> frozen dataclasses, validated at load without any network.

:func:`load_config` / :func:`parse_config` (in :mod:`.load`) return a :class:`Config` (the
dataclasses of :mod:`.model`) or raise :class:`~gateway.errors.ConfigError` listing every
problem; :mod:`.schema` is the one validator every section and plugin reads keys with;
:mod:`.plugins` maps protocol and output names to their modules.
"""

from . import model
from .load import load_config, parse_config
from .model import *  # noqa: F403 - the dataclasses, as listed in model.__all__

__all__ = ["load_config", "parse_config"]
__all__ += model.__all__
