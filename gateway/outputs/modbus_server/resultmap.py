"""The result map for SCADA engineers (``stiction-gateway result-map``): every loop's unit
id and first register, and each register's meaning, type and scaling, made from
:data:`gateway.wire.results.LAYOUT` (so it cannot drift from what the server serves).

:func:`layout_markdown` is the per-block table of docs/modbus-map.md, from the same
layout (a test holds the two equal).
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Iterator

from ...config.model import Config
from ...wire.results import LAYOUT, RESULT_BLOCK_SIZE

__all__ = ["COLUMNS", "MapRow", "layout_markdown", "map_csv", "map_rows", "map_table"]

COLUMNS = ("loop", "unit_id", "register", "offset", "field", "type", "word_order", "scale",
           "unit", "meaning")


@dataclasses.dataclass(frozen=True)
class MapRow:
    """One value of one loop's block: read ``type`` at ``register`` (0-based, function
    code 3 or 4) of ``unit_id``; engineering value = register value * ``scale``."""

    loop: str
    unit_id: int
    register: int
    offset: int
    field: str
    type: str
    word_order: str  # of 32-bit values; "-" for 16-bit ones
    scale: float
    unit: str
    meaning: str

    def cells(self) -> list[str]:
        return [str(getattr(self, c)) if c != "scale" else f"{self.scale:g}" for c in COLUMNS]


def map_rows(config: Config, loops: list[str] | None = None) -> Iterator[MapRow]:
    """The rows of every loop (or of ``loops``), in config order then register order."""
    server = config.modbus_server
    wanted = set(loops) if loops else None
    for lp in config.loops:
        if wanted is not None and lp.name not in wanted:
            continue
        unit = server.unit_id if lp.result_unit_id is None else lp.result_unit_id
        for f in LAYOUT:
            yield MapRow(lp.name, unit, lp.result_address + f.offset, f.offset, f.name,
                         f.type_name, server.word_order if f.width > 1 else "-", f.scale,
                         f.unit, f.meaning)


def map_csv(rows: Iterator[MapRow]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows(r.cells() for r in rows)
    return out.getvalue()


def map_table(rows: Iterator[MapRow]) -> str:
    """The rows as an aligned text table (the meaning last, not padded)."""
    cells = [list(COLUMNS), *(r.cells() for r in rows)]
    widths = [max(len(c[i]) for c in cells) for i in range(len(COLUMNS) - 1)]
    return "".join("  ".join([*(c.ljust(w) for c, w in zip(row, widths, strict=False)),
                              row[-1]]).rstrip() + "\n" for row in cells)


def layout_markdown() -> str:
    """The table of one block (docs/modbus-map.md, "One block of 20 registers per loop")."""
    lines = ["| offset | registers | type | unit | content |", "|---|---|---|---|---|"]
    for f in LAYOUT:
        regs = f"{f.width}" if f.type != "uint8" else f"{f.byte} byte"
        lines.append(f"| +{f.offset} | {regs} | {f.type} | {f.unit} | {f.meaning} |")
    end = max(f.offset + f.width for f in LAYOUT)
    if end < RESULT_BLOCK_SIZE:
        lines.append(f"| +{end}..+{RESULT_BLOCK_SIZE - 1} | {RESULT_BLOCK_SIZE - end} | - | "
                     f"- | reserved, 0 |")
    return "\n".join(lines) + "\n"
