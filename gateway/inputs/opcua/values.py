"""DataValues to raw values and qualities (one per point), and one log line per change of a
point's status:

=======================  ===========================================================
status / value           sample
=======================  ===========================================================
Good, finite number      the value, ``Quality.GOOD`` (scaled later, in core.points)
Uncertain                NaN, ``Quality.UNCERTAIN`` (a gap: analysis never uses it)
Bad (incl. a node that   NaN, ``Quality.BAD``; the device's other points go on
does not exist)
Good but not a finite    NaN, ``Quality.BAD`` (a string, an array, a boolean, NaN...)
number
=======================  ===========================================================

A read in which the server refuses *every* node (each a Bad status: ``BadNodeIdUnknown``
for node ids it does not have, ``BadUserAccessDenied``...) is not a read of bad values: the
device serves nothing, as a Modbus device refusing every request. :func:`refused` makes it
one :class:`~gateway.errors.DeviceError` of kind ``exception``, named by the status; the
poller calls the device down with that reason and its loops ``device_down``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
from asyncua import ua
from asyncua.ua.status_codes import StatusCodes
from numpy.typing import NDArray

from ...core.points import PointSpec, Quality
from ...errors import DeviceError
from .errors import status_name

__all__ = ["StatusLog", "convert", "refused"]

_log = logging.getLogger("gateway.inputs.opcua")


def convert(results: Sequence[ua.DataValue], read_index: Sequence[int], n: int
            ) -> tuple[NDArray[np.float64], NDArray[np.uint8], NDArray[np.uint32]]:
    """Raw values, qualities and status codes of ``n`` points from the DataValues read for
    the points ``read_index`` (points not read: BAD, BadNodeIdUnknown)."""
    raw = np.full(n, np.nan)
    quality = np.full(n, Quality.BAD, dtype=np.uint8)
    status = np.full(n, StatusCodes.BadNodeIdUnknown, dtype=np.uint32)
    for i, dv in zip(read_index, results, strict=True):
        code = dv.StatusCode.value if dv.StatusCode is not None else 0
        status[i] = code
        if code & 0x80000000:  # Bad
            continue
        if code & 0x40000000:  # Uncertain: a gap, with its own quality
            quality[i] = Quality.UNCERTAIN
            continue
        value = dv.Value.Value if dv.Value is not None else None
        if isinstance(value, int | float | np.number) and not isinstance(value, bool):
            x = float(value)
            if np.isfinite(x):
                raw[i] = x
                quality[i] = Quality.GOOD
                continue
        status[i] = StatusCodes.BadTypeMismatch  # for the log: not a usable number
    return raw, quality, status


_HINTS = {
    "BadNodeIdUnknown": "the server has none of these node ids: check them against its "
                        "address space (stiction-gateway browse {endpoint})",
    "BadNodeIdInvalid": "these node ids are not valid on this server: check them (stiction-"
                        "gateway browse {endpoint})",
    "BadUserAccessDenied": "the server does not let the gateway's user read them: check the "
                           "user's rights on the server",
    "BadNotReadable": "the server does not let the gateway's user read them: check the "
                      "user's rights on the server",
}


def refused(status: NDArray[np.uint32], points: Sequence[PointSpec],
            node_ids: Sequence[ua.NodeId], *, device: str, endpoint: str
            ) -> DeviceError | None:
    """The DeviceError of a read whose every point the server refused (a Bad status each,
    other than a value that is not a number), else None."""
    if not len(status) or not (status & 0x80000000).all() \
            or (status == StatusCodes.BadTypeMismatch).any():
        return None
    names = sorted({status_name(int(c)) for c in status})
    p = points[0]
    hint = _HINTS.get(names[0], "") if len(names) == 1 else ""
    text = (f"the server refused every one of its {len(status)} nodes ({', '.join(names)}; "
            f"the first: loop {p.loop} {p.role}, {node_ids[0].to_string()}): "
            f"{(hint or 'the server has no value for any of them').format(endpoint=endpoint)}")
    reason = f"nodes refused ({names[0]})" if len(names) == 1 else "nodes refused"
    return DeviceError(device, "exception", text, reason=reason)


class StatusLog:
    """Logs a point when its status turns uncertain or bad, and when it is good again."""

    def __init__(self, device: str, points: Sequence[PointSpec],
                 node_ids: Sequence[ua.NodeId]) -> None:
        self.device = device
        self.points = points
        self.node_ids = node_ids
        self.status = np.zeros(len(points), dtype=np.uint32)

    def update(self, status: NDArray[np.uint32]) -> None:
        for i in np.flatnonzero(status != self.status).tolist():
            p, code = self.points[i], int(status[i])
            if code & 0xC0000000:
                _log.warning("OPC UA device %s: loop %s %s (%s): %s", self.device, p.loop,
                             p.role, self.node_ids[i].to_string(), status_name(code))
            elif self.status[i] & 0xC0000000:
                _log.info("OPC UA device %s: loop %s %s good again", self.device, p.loop,
                          p.role)
        self.status = status
