"""The result-register map (docs/modbus-map.md), defined in this one place.

Each loop has a block of :data:`RESULT_BLOCK_SIZE` registers (:data:`EXTENDED_BLOCK_SIZE`
with ``modbus_server.block_registers: 32``) at its ``result_address`` on its
``result_unit_id``. :data:`LAYOUT` (and :data:`EXTENSION`) say which field sits at which
offset and how it is encoded; :func:`result_block` fills a block, :func:`decode_block`
reads one back, :data:`VERDICT_CODES` numbers the verdicts, and
:func:`overlapping_blocks` finds blocks that share registers (the config loader refuses
them). Adding a field is one :class:`Field` line in :data:`EXTENSION` (at the next free
offset, +29 on; the 20 registers of :data:`LAYOUT` are full) and one entry in
:func:`block_values`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment, Verdict

from .codec import TYPES, decode_registers, encode_values

__all__ = [
    "BLOCK_SIZES",
    "EXTENDED_BLOCK_SIZE",
    "EXTENSION",
    "LAYOUT",
    "MAX_RESULT_UNIT_ID",
    "NO_SOURCE_ADDRESS",
    "RESULT_BLOCK_SIZE",
    "RESULT_LOOPS_PER_UNIT",
    "ROLES",
    "VERDICT_CODES",
    "Field",
    "block_values",
    "decode_block",
    "layout",
    "loops_per_unit",
    "moved_indices",
    "moved_line",
    "overlapping_blocks",
    "result_block",
    "unit_images",
    "verdict_code",
]

RESULT_BLOCK_SIZE = 20
"""Registers per loop in the result server (offsets +0..+19): the default block, the one
every SCADA map made before the extended block reads."""
EXTENDED_BLOCK_SIZE = 32
"""The extended block (``modbus_server.block_registers: 32``): the 20 registers and
:data:`EXTENSION` at +20.., the rest reserved (0) for fields to come."""
BLOCK_SIZES = (RESULT_BLOCK_SIZE, EXTENDED_BLOCK_SIZE)
RESULT_LOOPS_PER_UNIT = 65536 // RESULT_BLOCK_SIZE
"""Loops whose result blocks fit one unit id's 16-bit register space (3,276; 2,048 of the
extended block: :func:`loops_per_unit`)."""
NO_SOURCE_ADDRESS = 65535
"""+24 of the extended block when the loop's group has no source loop (no block starts
there: a block needs at least 20 registers)."""
MAX_RESULT_UNIT_ID = 247

VERDICT_CODES: dict[str, int] = {
    "none": 0,
    Verdict.NOT_OSCILLATING: 1,
    Verdict.NO_STICTION: 2,
    Verdict.UNDETERMINED: 3,
    Verdict.STICTION: 4,
    Verdict.BAD_DATA: 5,
    "stale": 6,
    Verdict.VALVE_NOT_RESPONDING: 7,
    Verdict.WARMING_UP: 8,
    "device_down": 9,
    Verdict.PROPAGATED: 10,
}
"""Verdict codes of register +0 ("none": no assessment yet; "stale": no fresh samples;
"warming_up": the window is still filling and no oscillation is seen yet; "device_down":
stale because the loop's device is down, e.g. refusing every request; "propagated": the
loop carries a cycle whose source is another loop, or outside, see +18..+19)."""
ROLES = ("none", "source", "follower")
"""A loop's plant-wide role (register +18, high byte): its code is its position."""


@dataclasses.dataclass(frozen=True)
class Field:
    """One value of a block: its name, first register (offset in the block) and type; the
    ``unit`` and ``meaning`` SCADA engineers see (``stiction-gateway result-map``,
    docs/modbus-map.md); engineering value = register value * ``scale``. A ``uint8`` is
    one byte of its register: ``byte`` "high" or "low"."""

    name: str
    offset: int
    type: str  # a wire.codec type: uint16, uint32, float32, ...
    unit: str = ""
    meaning: str = ""
    scale: float = 1.0
    byte: str = ""

    @property
    def width(self) -> int:
        return 1 if self.type == "uint8" else TYPES[self.type][0]

    @property
    def type_name(self) -> str:
        """The type as the map shows it: ``uint8 (high byte)`` for a byte."""
        return f"{self.type} ({self.byte} byte)" if self.byte else self.type


_PERCENT = "% of valve span"  # the one unit of sizes (stiction.Sizes); metrics: / 100
_CODES = ", ".join(f"{code} {name.replace('_', ' ') if name != 'none' else 'no result yet'}"
                   for name, code in VERDICT_CODES.items())

LAYOUT: tuple[Field, ...] = (
    Field("code", 0, "uint16", "code", f"verdict: {_CODES}"),
    Field("seq", 1, "uint16", "count", "assessment sequence number: +1 on every new "
          "assessment, wraps 65535 -> 0, never goes back across reloads and restarts (after "
          "a crash it may jump ahead); if it stops changing, the analysis has stopped"),
    Field("stiction_index", 2, "float32", "0-1",
          "stiction index SI (>= 0.6 stiction-like, <= 0.4 not)"),
    Field("fd_percent", 4, "float32", _PERCENT, "fd, dynamic friction"),
    Field("fs_percent", 6, "float32", _PERCENT,
          "fs, static friction; NaN when the loop has no kp in the config"),
    Field("period_s", 8, "float32", "s", "oscillation period"),
    Field("jump_percent", 10, "float32", _PERCENT,
          "valve jump J = K (fs - fd), K = 1.99: how far the valve slips when it breaks "
          "free (measured from the valve's travel where the loop reads its position); NaN "
          "without fs"),
    Field("timestamp", 12, "uint32", "Unix s (UTC)", "time of the assessment"),
    Field("window_fill", 14, "float32", "0-1",
          "window fill: fraction of the loop's window holding good samples"),
    Field("confidence", 16, "float32", "0-1",
          "confidence of stiction, the analysis's learned decision from its tests (>= 0.87 "
          "is a stiction verdict, <= 0.5 no_stiction); NaN when no test ran (bad data, valve "
          "not responding)"),
    Field("plant_role", 18, "uint8", "code",
          "plant-wide role: 0 in no group, 1 source (the loop whose valve drives a cycle "
          "other loops share), 2 follower (it carries a cycle from elsewhere)", byte="high"),
    Field("plant_group", 18, "uint8", "number",
          "plant-wide group: the number (1-255) of the cycle the loop shares with other "
          "loops of its poll interval; 0 in no group", byte="low"),
    Field("plant_source", 19, "uint16", "loop index",
          "the group's source loop: its position in the config (result-map order, from "
          "1); 0 in no group, or when no loop read is the source (a cycle from outside)"),
)
"""Values not estimated are float32 NaN."""

EXTENSION: tuple[Field, ...] = (
    Field("judged", 20, "uint32", "Unix s (UTC)",
          "time of the analysis round that judged the verdict (+0) and the numbers shown: "
          "+12 unless the verdict is held (+22), then older: its age is +12 - +20; 0 "
          "without an assessment"),
    Field("hold", 22, "uint16", "code",
          "0 the verdict was judged by the latest round; 1 held back while a new one waits "
          "for its rounds (verdict hysteresis); 2 held through warming up (an outage or a "
          "restart restarted the window; at most the loop's window_s after +20, then code "
          "8)"),
    Field("source_unit_id", 23, "uint16", "unit id",
          "the group's source loop's result unit id (with +24: its block, which stays "
          "when loops are added, removed or reordered; +19 counts places in the config); "
          "0 when +24 is 65535"),
    Field("source_address", 24, "uint16", "register",
          "the group's source loop's result_address, the first register of its block; "
          "65535 in no group, or when no loop read is the source"),
    Field("rank", 25, "uint16", "place",
          "the loop's place in the list of valves to check, worst first: 1 the worst, by "
          "its suspicion (+26); 0 without an assessment"),
    Field("suspicion", 26, "float32", "score",
          "the loop's suspicion: confidence of stiction (+16) x what its cycle costs (the "
          "PV amplitude, where the PV has a range) x its priority; 0 for a loop not judged "
          "on a cycle; NaN without an assessment"),
    Field("position_use", 28, "uint16", "code",
          "the valve's position in the latest assessment: 0 no position given (none "
          "configured, or no assessment), 1 used (its travel decided), 2 could not tell "
          "(too gappy or too few reversals: OP and PV decided), 3 not a position (it moved "
          "against OP, in another scale, late, or held while PV moved: OP and PV decided, "
          "the reason says why)"),
)
"""The extended block's fields after the 20 registers (``block_registers: 32``); +29..+31
are reserved (read 0) for the fields to come, which take the next free offsets."""

POSITION_USE_CODES = {None: 0, "used": 1, "could_not_tell": 2, "not_a_position": 3}
"""Register +28's code of :attr:`stiction.Assessment.position_use`."""


def layout(size: int = RESULT_BLOCK_SIZE) -> tuple[Field, ...]:
    """The fields of a block of ``size`` registers (:data:`BLOCK_SIZES`)."""
    return LAYOUT if size < EXTENDED_BLOCK_SIZE else LAYOUT + EXTENSION


def loops_per_unit(size: int = RESULT_BLOCK_SIZE) -> int:
    """Blocks of ``size`` registers in one unit id's register space."""
    return 65536 // size


class LoopResultLike(Protocol):
    """What a block is made of (``gateway.core.store.LoopResult`` has it; the extended
    block reads its ``judged_at`` and ``hold`` too, where it has them)."""

    @property
    def assessment(self) -> Assessment: ...
    @property
    def seq(self) -> int: ...
    @property
    def t(self) -> float: ...
    @property
    def window_fill(self) -> float: ...


def verdict_code(result: LoopResultLike | None, stale: bool = False,
                 down: bool = False) -> int:
    """Register +0 of a loop: stale (device_down if its device is ``down``) wins over any
    assessment."""
    if stale:
        return VERDICT_CODES["device_down" if down else "stale"]
    if result is None:
        return VERDICT_CODES["none"]
    return VERDICT_CODES[result.assessment.verdict]


def _num(x: float | None) -> float:
    return math.nan if x is None else float(x)


def block_values(result: LoopResultLike | None, code: int,
                 plant: tuple[int, int, int] = (0, 0, 0),
                 source: tuple[int, int] = (0, NO_SOURCE_ADDRESS),
                 size: int = RESULT_BLOCK_SIZE, *,
                 rank: tuple[int, float] = (0, math.nan)) -> dict[str, float]:
    """The field values of a block of ``size`` registers (:func:`_values`; ``rank``: the
    loop's place in the list worst first and its suspicion)."""
    names = {f.name for f in layout(size)}
    values = _values(result, code, plant, source)
    values["rank"], values["suspicion"] = float(rank[0]), rank[1]
    return {k: v for k, v in values.items() if k in names}


def _values(result: LoopResultLike | None, code: int, plant: tuple[int, int, int],
            source: tuple[int, int]) -> dict[str, float]:
    """The field values of one loop's block (fields left out are 0). Without an assessment
    (none yet, or stale since start) every float is NaN, never 0: a SCADA screen must not
    show "fd 0.0 %" for a loop never assessed; the sequence number and time are 0.
    ``plant``: the loop's (group number, role code, source loop's index); ``source``: the
    source loop's block (unit id, address) for the extended block."""
    group, role, index = plant
    plant_values = {"plant_role": role, "plant_group": group, "plant_source": index,
                    "source_unit_id": source[0], "source_address": source[1]}
    if result is None:
        return {"code": code, **{f.name: math.nan for f in LAYOUT if f.type == "float32"},
                **plant_values}
    a = result.assessment
    size = a.sizes()
    if size is not None and not size.of_span:  # the gateway always knows op_range
        size = None
    return {"code": code, "seq": result.seq % 65536,
            "stiction_index": _num(a.stiction_index),
            "fd_percent": _num(size.fd if size else None),
            "fs_percent": _num(size.fs if size else None),
            "period_s": _num(a.period_s), "jump_percent": _num(size.jump if size else None),
            "timestamp": max(0, int(result.t)),
            "window_fill": result.window_fill, "confidence": _num(a.confidence),
            "judged": max(0, int(getattr(result, "judged_at", result.t))),
            "hold": int(getattr(result, "hold", 0)),
            "position_use": POSITION_USE_CODES.get(a.position_use, 0), **plant_values}


def result_block(result: LoopResultLike | None, *, code: int, word_order: str = "big",
                 plant: tuple[int, int, int] = (0, 0, 0), size: int = RESULT_BLOCK_SIZE,
                 source: tuple[int, int] = (0, NO_SOURCE_ADDRESS),
                 rank: tuple[int, float] = (0, math.nan)) -> NDArray[np.uint16]:
    """The ``size`` registers of one loop's block (``plant``, ``source``, ``rank``: see
    :func:`block_values`)."""
    block = np.zeros(size, dtype=np.uint16)
    values = block_values(result, code, plant, source, size, rank=rank)
    for f in layout(size):
        if f.name not in values:
            continue
        if f.type == "uint8":
            byte = int(values[f.name]) & 0xFF
            block[f.offset] |= byte << 8 if f.byte == "high" else byte
            continue
        block[f.offset:f.offset + f.width] = encode_values([values[f.name]], f.type,
                                                           word_order)[0]
    return block


def _decoded(regs: NDArray[np.uint16], f: Field, word_order: str) -> float:
    if f.type == "uint8":
        reg = int(regs[f.offset])
        return float(reg >> 8 if f.byte == "high" else reg & 0xFF)
    return float(decode_registers(regs[f.offset:f.offset + f.width], f.type, word_order)[0])


def decode_block(registers: Iterable[int] | NDArray[np.uint16], word_order: str = "big"
                 ) -> dict[str, float]:
    """The field values of a block read from the server (an extended block's too, given
    its 32 registers; ``reserved``: sum of the registers after the last field)."""
    regs = np.asarray(list(registers) if not isinstance(registers, np.ndarray) else registers,
                      dtype=np.uint16)
    size = EXTENDED_BLOCK_SIZE if len(regs) >= EXTENDED_BLOCK_SIZE else RESULT_BLOCK_SIZE
    fields = layout(size)
    out = {f.name: _decoded(regs, f, word_order) for f in fields}
    end = max(f.offset + f.width for f in fields)
    out["reserved"] = float(regs[end:size].astype(np.int64).sum())
    return out


def overlapping_blocks(blocks: Iterable[tuple[str, int, int]], size: int = RESULT_BLOCK_SIZE
                       ) -> Iterator[tuple[str, int, int, str, int]]:
    """Pairs of neighbouring blocks (in unit id and address order) that share registers.

    ``blocks`` are ``(loop, unit id, address)``; yields ``(loop, unit id, address, other
    loop, other address)`` for each block that starts inside the block before it. The same
    address on two unit ids is fine."""
    ordered = sorted(blocks, key=lambda b: (b[1], b[2]))
    for (pname, punit, pa), (name, unit, a) in itertools.pairwise(ordered):
        if unit == punit and a < pa + size:
            yield name, unit, a, pname, pa


def unit_images(addresses: Mapping[int, Iterable[int]], size: int = RESULT_BLOCK_SIZE
                ) -> dict[int, NDArray[np.uint16]]:
    """Zeroed register images per unit id, each long enough for its blocks' addresses."""
    return {u: np.zeros(max([size, *(a + size for a in addrs)]), dtype=np.uint16)
            for u, addrs in addresses.items()}


def moved_indices(old: Sequence[str], new: Sequence[str]) -> list[tuple[str, int, int]]:
    """``(loop, old index, new index)`` (from 1) of the loops in both lists whose place
    changed: register +19 (a plant group's source loop, by its place in the config) now
    names another loop for a SCADA table made before (issue 38 item 13)."""
    at = {name: k for k, name in enumerate(old, start=1)}
    return [(name, at[name], k) for k, name in enumerate(new, start=1)
            if name in at and at[name] != k]


def moved_line(moved: Sequence[tuple[str, int, int]], shown: int = 5) -> str:
    """The WARNING line for :func:`moved_indices`' loops."""
    listed = ", ".join(f"{name} {a} -> {b}" for name, a, b in moved[:shown])
    more = f" and {len(moved) - shown} more" if len(moved) > shown else ""
    return (f"{len(moved)} loop(s) moved in the config's order ({listed}{more}): register "
            "+19 (a plant group's source loop, by its place in the config) now numbers them "
            "so; a SCADA table that maps +19 to loops needs `stiction-gateway result-map`'s "
            "order (the extended block's +23/+24 name the source's block instead, which "
            "does not move)")
