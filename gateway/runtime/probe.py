"""``stiction-gateway probe``: read each loop's OP and PV once, as the gateway would.

Per device (all at once): the source its protocol plugin builds for the loops asked for
(the same requests, decoding and word order as the poller's), one connect, one read,
close; then the core's :class:`~gateway.core.points.PointTable` turns raw values into
engineering values and judges them (:meth:`~gateway.core.points.PointTable.judge`: scale,
offset, range, op_range, NaN, subnormal, magnitude): an implausible value is shown as
``IMPLAUSIBLE`` with its likely cause (:func:`~gateway.core.points.explain`: an address off
by one, the word order), the words the poller logs. Nothing is written anywhere. A device
that cannot be read is a :class:`~gateway.errors.DeviceError` naming the device; a point
that came back bad says why (the Modbus request and its exception in words with the fix,
the OPC UA status such as ``BadNodeIdUnknown``).
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
from collections.abc import Sequence

from ..config import Config, DeviceConfig, LoopConfig
from ..core.points import Implausible, PointTable, Quality, explain
from ..errors import ConfigError, DeviceError
from ..inputs.base import PointStatus, Source
from .reload import device_points, plugin_source

__all__ = ["DeviceProbe", "ProbeRow", "format_probe", "probe"]


@dataclasses.dataclass(frozen=True)
class ProbeRow:
    """One point read once: ``raw`` as decoded, ``value`` in engineering units (NaN unless
    ``quality`` is GOOD) and what the protocol said of it (``status``, '' when nothing)."""

    loop: str
    role: str
    device: str
    address: str
    raw: float
    value: float
    quality: Quality
    status: str = ""
    cause: Implausible = Implausible.NONE  # why the value read is implausible

    @property
    def shown_quality(self) -> str:
        """``IMPLAUSIBLE`` for a value read but implausible, else the quality's name."""
        return "IMPLAUSIBLE" if self.cause != Implausible.NONE else self.quality.name


@dataclasses.dataclass(frozen=True)
class DeviceProbe:
    """One device: its rows, or ``error`` when it could not be read at all; ``errors`` are
    partial failures (a request answered with an exception)."""

    device: str
    rows: tuple[ProbeRow, ...] = ()
    error: DeviceError | None = None
    errors: tuple[DeviceError, ...] = ()

    @property
    def ok(self) -> bool:
        return self.error is None and all(r.quality == Quality.GOOD for r in self.rows)


def select_loops(config: Config, names: Sequence[str]) -> list[LoopConfig]:
    """The loops named (all without names); ConfigError naming any unknown one."""
    if not names:
        return list(config.loops)
    known = {lp.name for lp in config.loops}
    unknown = [n for n in dict.fromkeys(names) if n not in known]
    if unknown:
        raise ConfigError([f"{config.source}: no loop {n!r}" for n in unknown])
    wanted = set(names)
    return [lp for lp in config.loops if lp.name in wanted]


async def probe(config: Config, names: Sequence[str] = ()) -> list[DeviceProbe]:
    """Read the loops ``names`` (default all) once; one :class:`DeviceProbe` per device
    that has any of them, in config order."""
    loops = select_loops(config, names)
    devices = [d for d in config.devices if any(lp.device == d.name for lp in loops)]
    return list(await asyncio.gather(*(
        _probe_device(d, [lp for lp in loops if lp.device == d.name],
                      config.gateway.time_scale) for d in devices)))


async def _probe_device(device: DeviceConfig, loops: list[LoopConfig],
                        time_scale: float) -> DeviceProbe:
    points = device_points(loops)
    source: Source = plugin_source(device, points, time_scale)
    limit = 4 * device.timeout_s + 2.0
    try:
        async with asyncio.timeout(limit):
            await source.connect()
            result = await source.read()
    except DeviceError as exc:
        return DeviceProbe(device.name, error=exc)
    except TimeoutError:
        return DeviceProbe(device.name, error=DeviceError(
            device.name, "timeout", f"no answer within {limit:g} s"))
    finally:
        await source.close()
    values, quality, causes = PointTable(points).judge(result.values, result.quality)
    status = source.point_status() if isinstance(source, PointStatus) else []
    rows = tuple(ProbeRow(p.loop, p.role, device.name, str(p.address), float(result.values[i]),
                          float(values[i]), Quality(int(quality[i])),
                          (status[i] if i < len(status) else "")
                          or explain(p, float(result.values[i]), int(causes[i])),
                          Implausible(int(causes[i])))
                 for i, p in enumerate(points))
    return DeviceProbe(device.name, rows, errors=result.errors)


def _num(x: float) -> str:
    return "nan" if math.isnan(x) else f"{x:.7g}"


def format_probe(results: Sequence[DeviceProbe]) -> str:
    """The rows of every device read, as an aligned table."""
    head = ["loop", "point", "device", "address", "raw", "value", "quality", "status"]
    cells = [head]
    for dev in results:
        for r in dev.rows:
            cells.append([r.loop, r.role, r.device, r.address, _num(r.raw), _num(r.value),
                          r.shown_quality, r.status])
    widths = [max(len(c[i]) for c in cells) for i in range(len(head))]
    return "".join("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
                   + "\n" for row in cells)
