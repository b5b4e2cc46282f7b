"""Result blocks for loops that do not set ``result_address`` (docs/configuration.md,
"Result addresses").

The rule, per result unit id: the loops without ``result_address`` take, in config order,
the lowest free block start 0, 20, 40, ... (multiples of the block's length,
``modbus_server.block_registers``: 0, 32, 64, ... for the extended block); a
block is free when no loop with an explicit ``result_address`` on that unit id overlaps
it and no earlier loop took it. So an explicit address always wins, and appending loops
never moves a block already assigned; removing or reordering loops moves the blocks of
the loops after them (pin those with an explicit ``result_address``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence

from ..wire.results import RESULT_BLOCK_SIZE, loops_per_unit
from .model import Config, LoopConfig

__all__ = ["assign_result_addresses", "describe_assigned"]


def _taken_slots(blocks: Iterable[tuple[str, int, int]], n: int) -> dict[int, set[int]]:
    """Per unit id, the block slots (address // n) an explicit block of ``n`` registers
    overlaps."""
    taken: dict[int, set[int]] = {}
    for _name, unit, address in blocks:
        first = max(0, -(-(address - n + 1) // n))  # ceil((address - n + 1) / n)
        last = min(loops_per_unit(n) - 1, (address + n - 1) // n)
        taken.setdefault(unit, set()).update(range(first, last + 1))
    return taken


def assign_result_addresses(loops: Sequence[LoopConfig],
                            blocks: Iterable[tuple[str, int, int]],
                            size: int = RESULT_BLOCK_SIZE
                            ) -> tuple[list[LoopConfig], list[str], dict[str, str]]:
    """Fill in the ``result_address`` of the loops that have None, by the rule above.

    ``blocks`` are the explicit ``(loop, unit id, address)`` blocks of the config (also of
    loops that are otherwise invalid). Returns the loops (in the same order), the names of
    those given an address, and ``{loop: problem}`` for loops that found no free block."""
    taken = _taken_slots(blocks, size)
    per_unit = loops_per_unit(size)
    cursor: dict[int, int] = {}
    out: list[LoopConfig] = []
    assigned: list[str] = []
    full: dict[str, str] = {}
    for lp in loops:
        if lp.result_address is not None:
            out.append(lp)
            continue
        unit = lp.result_unit_id if lp.result_unit_id is not None else 0
        used = taken.setdefault(unit, set())
        k = cursor.get(unit, 0)
        while k in used:
            k += 1
        if k >= per_unit:
            full[lp.name] = (f"no free result block left on result unit id {unit} "
                             f"({per_unit:,} blocks of {size} "
                             f"registers): set result_unit_id (or result_address)")
            cursor[unit] = k
            continue
        used.add(k)
        cursor[unit] = k + 1
        assigned.append(lp.name)
        out.append(dataclasses.replace(lp, result_address=k * size))
    return out, assigned, full


def describe_assigned(config: Config, *, short_run: int = 3) -> list[str]:
    """Lines saying which result blocks the loader assigned (for check-config): runs of
    loops that follow each other in config order and in address on one unit id are one
    line, shorter runs one line per loop."""
    if not config.assigned:
        return []
    size = config.modbus_server.block_registers
    names = set(config.assigned)
    runs: list[list[LoopConfig]] = []
    for lp in config.loops:
        if lp.name not in names:
            if runs and runs[-1]:
                runs.append([])
            continue
        run = runs[-1] if runs else None
        if run and run[-1].result_unit_id == lp.result_unit_id \
                and run[-1].result_address + size == lp.result_address:
            run.append(lp)
        else:
            runs.append([lp])
    lines = [f"{config.source}: result_address assigned to {len(names)} loop(s) without one "
             f"(unit id, first of {size} registers):"]
    for run in runs:
        if not run:
            continue
        if len(run) <= short_run:
            lines += [f"  {lp.name}: unit id {lp.result_unit_id}, result_address "
                      f"{lp.result_address}" for lp in run]
        else:
            a, b = run[0], run[-1]
            lines.append(f"  {a.name} .. {b.name} ({len(run)} loops, in config order): "
                         f"unit id {a.result_unit_id}, result_address {a.result_address}, "
                         f"{a.result_address + size}, .. {b.result_address}")
    return lines
