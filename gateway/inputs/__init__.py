"""Input adapters, one module per protocol behind the small :class:`DeviceInput` interface."""

from .base import DeviceInput, PointSpec, Quality, ReadResult

__all__ = ["DeviceInput", "PointSpec", "Quality", "ReadResult"]
