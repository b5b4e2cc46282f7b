"""Outputs: one folder per sink, each a plugin behind the small :class:`Sink` interface.

``modbus_server/`` serves the result registers, ``prometheus/`` the metrics, ``statefile/``
keeps windows and results across restarts, ``memory/`` records what it is shown (tests).
Each module defines ``create_sink(binding, **options) -> Sink`` and is registered by one
line in :data:`gateway.config.plugins.OUTPUTS`.
"""

from .base import Binding, Sink

__all__ = ["Binding", "Sink"]
