"""The result map for SCADA engineers (``stiction-gateway result-map``): every loop's unit
id and first register, and each register's meaning, type and scaling, made from
:data:`gateway.wire.results.LAYOUT` (so it cannot drift from what the server serves). Each
register is named three ways: 0-based as on the wire (``register``), and as the 1-based
references of the holding and the input registers (``holding`` 400001 + register, read
with function code 3; ``input`` 300001 + register, function code 4), which hold the same
values.

:func:`layout_markdown` is the per-block table of docs/modbus-map.md, from the same
layout (a test holds the two equal).
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Iterator

from ...config.model import Config
from ...wire.results import EXTENDED_BLOCK_SIZE, EXTENSION, LAYOUT, RESULT_BLOCK_SIZE, layout

__all__ = ["COLUMNS", "READ_WITH", "MapRow", "layout_markdown", "map_csv", "map_rows",
           "map_table"]

COLUMNS = ("loop", "unit_id", "register", "holding", "input", "offset", "field", "type",
           "word_order", "scale", "unit", "meaning")
READ_WITH = ("read as holding registers (function code 3, references 4xxxxx) or as input "
             "registers (function code 4, references 3xxxxx): both hold the same values; "
             "register: 0-based, as on the wire")
"""The first line of the table (:func:`map_table`)."""


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

    @property
    def holding(self) -> int:
        """The 1-based (Modicon, six-digit) reference of the holding register."""
        return 400001 + self.register

    @property
    def input(self) -> int:
        """The 1-based (Modicon, six-digit) reference of the input register."""
        return 300001 + self.register

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
        for f in layout(server.block_registers):
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
    """The rows as an aligned text table (the meaning last, not padded), under a line that
    says which registers to read (:data:`READ_WITH`)."""
    cells = [list(COLUMNS), *(r.cells() for r in rows)]
    widths = [max(len(c[i]) for c in cells) for i in range(len(COLUMNS) - 1)]
    lines = ["  ".join([*(c.ljust(w) for c, w in zip(row, widths, strict=False)),
                        row[-1]]).rstrip() for row in cells]
    return "\n".join([READ_WITH, *lines]) + "\n"


def layout_markdown(extension: bool = False) -> str:
    """The table of one block (docs/modbus-map.md, "One block of 20 registers per loop"), or
    of the extended block's registers after those 20 (``extension``)."""
    fields, size = (EXTENSION, EXTENDED_BLOCK_SIZE) if extension else (LAYOUT,
                                                                      RESULT_BLOCK_SIZE)
    lines = ["| offset | registers | type | unit | content |", "|---|---|---|---|---|"]
    for f in fields:
        regs = f"{f.width}" if f.type != "uint8" else f"{f.byte} byte"
        lines.append(f"| +{f.offset} | {regs} | {f.type} | {f.unit} | {f.meaning} |")
    end = max(f.offset + f.width for f in fields)
    if end < size:
        lines.append(f"| +{end}..+{size - 1} | {size - end} | - | - | reserved, 0 |")
    return "\n".join(lines) + "\n"
