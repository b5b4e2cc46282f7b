"""Configuration: YAML -> frozen dataclasses, validated at load without any network."""

from .load import *  # noqa: F403
from .load import __all__ as __all__
