"""The gateway's exception root. Adapters map third-party errors (pymodbus, asyncua) to these."""

from __future__ import annotations

from typing import ClassVar

__all__ = ["ConfigError", "DeviceError", "GatewayError"]


class GatewayError(Exception):
    """Root of every exception raised by :mod:`gateway`."""


class ConfigError(GatewayError):
    """A configuration file cannot be used. ``problems`` lists every problem found, each a
    line naming the file, the device or loop, and the key."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = list(problems)


class DeviceError(GatewayError):
    """A device could not be reached or answered badly.

    ``kind`` is a short fixed word usable as a metric label: ``connect`` (refused or
    unreachable), ``timeout`` (no answer in time), ``exception`` (the device answered with a
    protocol exception, e.g. a Modbus exception code), ``auth`` (login or certificate
    refused), ``protocol`` (malformed answer or other protocol error).

    ``reason`` is a few words a plant engineer can act on, the same in the log and in the
    ``reason`` label of ``stiction_device_down_reason``: by default the kind's own words
    (:data:`REASONS`); a protocol may say more (``unit id 5 not served``, ``illegal data
    address``). It never holds a value read or the error text, so the label's values stay
    few.
    """

    KINDS = ("connect", "timeout", "exception", "auth", "protocol")
    REASONS: ClassVar[dict[str, str]] = {"connect": "no connection", "timeout": "no answer",
                                         "exception": "requests refused",
                                         "auth": "login refused",
                                         "protocol": "protocol error"}

    def __init__(self, device: str, kind: str, message: str, *,
                 reason: str | None = None) -> None:
        if kind not in self.KINDS:
            raise ValueError(f"unknown DeviceError kind {kind!r}")
        super().__init__(f"device {device}: {message}")
        self.device = device
        self.kind = kind
        self.reason = reason or self.REASONS[kind]
