"""Modbus exception codes in words, with what to do: the log, ``probe`` and the metrics say
the same.

A PLC that answers a read with an exception did answer: the request is wrong for it, or
it cannot serve it now. :func:`refusal` turns the code of one refused request into

* a *reason*, a few words from a fixed vocabulary (:data:`NAMES`, or ``unit id N not
  served``): the ``exception`` label of ``stiction_poll_refused_requests`` and the
  ``reason`` label of ``stiction_device_down_reason``;
* a *message*: the request, the code in words and the fix, naming the loops whose points
  the request holds and, for loops from a tag list, their line (``loops.csv: line 4``).

Addresses in the config are 0-based protocol addresses (the register number on the wire):
a 1-based "4xxxx" reference from a PLC manual, 40001, is register 0. An address that looks
like one is named with the register it probably means.
"""

from __future__ import annotations

from collections.abc import Sequence

from ...core.points import PointSpec

__all__ = ["GATEWAY_CODES", "NAMES", "exception_name", "points_text", "refusal"]

NAMES: dict[int, str] = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
}
"""The exception codes of the Modbus application protocol (V1.1b3, section 7)."""
GATEWAY_CODES = frozenset({10, 11})
"""Codes about the unit id, not the registers: the device behind it is not reached."""
FIRST_REFERENCE = {"holding": 40001, "input": 30001}
"""The 1-based reference of register 0 in the old Modicon numbering, by table."""


def exception_name(code: int | None) -> str:
    """``illegal data address`` for 2; ``exception code 99`` for a code the standard has
    not."""
    if code is None:
        return "exception without a code"
    return NAMES.get(code, f"exception code {code}")


def refusal(code: int | None, table: str, address: int, count: int, *, unit: int,
            points: Sequence[PointSpec]) -> tuple[str, str]:
    """``(reason, message)`` of a read of ``count`` registers of ``table`` from ``address``
    on ``unit`` answered with exception ``code``; ``points`` are the points it holds."""
    name = exception_name(code)
    last = address + count - 1
    head = f"{table} {address}+{count}: {name}" + (f" (exception {code})" if code in NAMES
                                                  else "")
    where = points_text(points)
    if code == 10:
        return (f"unit id {unit} not served",
                f"{head}: unit id {unit} is not served by the PLC (or by the Modbus "
                f"gateway in front of it); set the device's unit_id to the one it serves "
                f"(1 for most PLCs; behind a TCP-to-serial gateway, the device's address on "
                f"the serial line)")
    if code == 11:
        return (f"unit id {unit} not answering",
                f"{head}: the Modbus gateway got no answer from unit id {unit}; check the "
                f"device's unit_id, and that the device behind the gateway is powered and "
                f"wired")
    if code == 2:
        fix = (f"{head}: the PLC's map lacks register {address}" if count == 1 else
               f"{head}: registers {address}..{last} are outside the PLC's map (some or "
               f"all)")
        fix += (f"; check the address of {where} against the PLC's register list; "
                f"addresses are 0-based: 40001 is 0")
        fix += _references(points, table)
        if len({(p.loop, p.role) for p in points}) > 1 \
                and _used(points, address, count) < count:
            fix += ("; if each of them is in the map, the PLC refuses the unused registers "
                    "read between them: set the device's merge_gap to 0")
        return name, fix
    if code == 1:
        other = "input" if table == "holding" else "holding"
        return name, (f"{head}: the PLC does not serve {table} registers (function "
                      f"{3 if table == 'holding' else 4}); check the table of {where} "
                      f"(table: {other}?)")
    if code == 3:
        return name, (f"{head}: the PLC refuses to read {count} registers at once here; "
                      f"lower the device's max_registers_per_request, or check the "
                      f"addresses of {where}")
    if code in (5, 6):
        return name, f"{head}: the PLC is busy; it may answer the next poll ({where})"
    if code in (4, 8):
        return name, (f"{head}: the PLC failed while reading {where}; see its "
                      f"diagnostics")
    return name, f"{head}: see the PLC's manual ({where})"


def points_text(points: Sequence[PointSpec], limit: int = 3) -> str:
    """``TIC301 op and pv (loops.csv: line 4), FIC101 pv``: the loops of ``points`` (at
    most ``limit``, then "and N more loops"), their roles and where each loop is listed."""
    loops: dict[str, list[PointSpec]] = {}
    for p in points:
        loops.setdefault(p.loop, []).append(p)
    if not loops:
        return "no point"
    parts = []
    for loop, pts in list(loops.items())[:limit]:
        roles = " and ".join(dict.fromkeys(p.role for p in pts))
        origin = pts[0].origin
        parts.append(f"{loop} {roles}" + (f" ({origin})" if origin else ""))
    more = len(loops) - limit
    return ", ".join(parts) + (f" and {more} more loop(s)" if more > 0 else "")


def _used(points: Sequence[PointSpec], address: int, count: int) -> int:
    """How many of the request's registers a point reads (the rest: a gap read to save a
    request, which some PLCs refuse)."""
    used = {a.address + k for p in points for a in [p.address]
            for k in range(int(getattr(a, "width", 0)))}
    return len(used & set(range(address, address + count)))


def _references(points: Sequence[PointSpec], table: str) -> str:
    """``; FIC101 op at 40001 looks like a 4xxxx reference: register 0?`` for each point
    whose address looks like a 1-based reference of its table."""
    first = FIRST_REFERENCE.get(table)
    if first is None:
        return ""
    hints = []
    for p in points:
        a = getattr(p.address, "address", None)
        if isinstance(a, int) and first <= a < first + 10000:
            hints.append(f"{p.loop} {p.role} at {a} looks like a 1-based "
                         f"{str(first)[0]}xxxx reference: register {a - first}?")
    return "".join(f"; {h}" for h in hints[:3])
