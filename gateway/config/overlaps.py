"""Points of one device that read the same registers: refused unless both say ``shared``.

Two loops reading the same registers, or an OP overlapping its own PV, is almost always a
typing error in the tag list (the same row copied, an address off by two); the gateway
would poll happily and diagnose one loop's signals as another's. A point marked
``shared: true`` may overlap another point marked so (a split-range pair's common PV).

What "the same registers" means is the protocol's: an input plugin may define
``point_span(address) -> (space, first, end)`` (``end`` exclusive; points of one ``space``
overlap when their spans do), ``span_text(space, first, end)`` for messages and
``SPAN_WORDS`` (verb, what a span is, what a point's key holds: Modbus ``("are",
"registers", "address")``, the default; OPC UA ``("is", "node", "node id")``: two points of
one node id). A protocol without ``point_span`` is not checked.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from typing import Any

from .model import DeviceConfig, LoopConfig
from .plugins import input_plugin
from .schema import Section

__all__ = ["SPAN_WORDS", "check_overlaps"]

SPAN_WORDS = ("are", "registers", "address")
"""How a message names a span (Modbus registers), unless the plugin says otherwise."""


def check_overlaps(sections: Mapping[str, Section], devices: Sequence[DeviceConfig],
                   loops: Sequence[LoopConfig]) -> None:
    """One problem per point whose registers overlap an earlier point's (in address order,
    then config order) on its device, on the later loop's ``op``/``pv`` key."""
    by_device: dict[str, list[LoopConfig]] = {}
    for lp in loops:
        by_device.setdefault(lp.device, []).append(lp)
    for dev in devices:
        plugin = input_plugin(dev.protocol)
        if getattr(plugin, "point_span", None) is not None and dev.name in by_device:
            _check_device(sections, by_device[dev.name], plugin)


def _check_device(sections: Mapping[str, Section], loops: Sequence[LoopConfig],
                  plugin: Any) -> None:
    span = plugin.point_span
    text = getattr(plugin, "span_text", _span_text)
    verb, noun, address = getattr(plugin, "SPAN_WORDS", SPAN_WORDS)
    key = getattr(plugin, "POINT_ADDRESS_KEY", "address")
    spans: list[tuple[Hashable, int, int, int, str, str, bool]] = []
    for order, lp in enumerate(loops):
        for role, p in (("op", lp.op), ("pv", lp.pv)):
            space, first, end = span(p.address)
            spans.append((space, first, end, order, lp.name, role, p.shared))
    spans.sort(key=lambda s: (str(s[0]), s[1], s[3]))
    reach: tuple[Hashable, int, int, int, str, str, bool] | None = None
    for cur in spans:
        space, first, end, _order, name, role, shared = cur
        if reach is not None and reach[0] == space and first < reach[2] \
                and not (shared and reach[6]):
            other = "its own " + reach[5] if reach[4] == name else \
                f"loop {reach[4]}'s {reach[5]}"
            lo, hi = max(first, reach[1]), min(end, reach[2])
            sec = sections.get(name)
            what = (f"{text(space, first, end)} {verb} {other}'s {noun} too"
                    if (first, end) == (reach[1], reach[2]) else
                    f"{text(space, first, end)} overlaps {other} "
                    f"({text(reach[0], reach[1], reach[2])}) at {text(space, lo, hi)}")
            if sec is not None:
                sec.error(f"{role}.{key}", (
                    f"{what}: a wrong {address}? If both points read the same value on "
                    f"purpose (a split-range pair's PV), mark both shared: true"))
        if reach is None or reach[0] != space or end > reach[2]:
            reach = cur


def _span_text(space: Hashable, first: int, end: int) -> str:
    return f"{space} {first}" if end - first == 1 else f"{space} {first}..{end - 1}"
