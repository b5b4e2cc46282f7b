"""Tag lists: loops from a CSV file (``loops_csv:`` in the config, and
``stiction-gateway import-tags``), documented in docs/configuration.md ("Tag lists").

A tag list is a spreadsheet export: a header row naming the columns of :data:`COLUMNS`
(any order, any case; ``,``, ``;`` or tab separated; lines starting with ``#`` and empty
lines are skipped), then one loop per row. Each row becomes the loop mapping a YAML config
would hold and is read by the loader like any other loop, with the one validator: every
problem of every row is reported at once, named by the file, the line, the loop and the
column::

    loops.csv: line 7: loop FIC107: column 'type': must be one of int16, ..., was 'flaot32'
"""

from __future__ import annotations

import csv
import dataclasses
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from .plugins import input_plugin
from .reading import read_bytes
from .schema import MISSING, Problems, Section

__all__ = ["COLUMNS", "REQUIRED_COLUMNS", "TagRow", "TagTable", "read_tag_file",
           "read_tag_text", "tag_entries", "tag_tables"]

COLUMNS: dict[str, str] = {
    "name": "loop name (unique)",
    "device": "the device's name",
    "op": "OP address: a Modbus register number (0-based) or an OPC UA node id",
    "pv": "PV address, likewise",
    "type": "Modbus register type of OP and PV (int16, uint16, int32, uint32, float32, "
            "float64)",
    "op_type": "OP's type, if not `type`",
    "pv_type": "PV's type, if not `type`",
    "table": "Modbus table of OP and PV: holding (default) or input",
    "op_table": "OP's table, if not `table`",
    "pv_table": "PV's table, if not `table`",
    "shared": "true: OP and PV may read registers another loop's point reads too, if it "
              "says so as well (default false)",
    "op_shared": "OP's shared, if not `shared`",
    "pv_shared": "PV's shared, if not `shared` (a split-range pair's common PV)",
    "op_scale": "OP = raw * op_scale + op_offset (default 1)",
    "op_offset": "(default 0)",
    "pv_scale": "PV = raw * pv_scale + pv_offset (default 1)",
    "pv_offset": "(default 0)",
    "position": "the valve's position, as its positioner reports it (optional): an address "
                "like OP's, read in OP units (% of span; use position_scale/_offset)",
    "position_type": "the position's type, if not `type`",
    "position_table": "the position's table, if not `table`",
    "position_shared": "the position's shared, if not `shared`",
    "position_scale": "position = raw * position_scale + position_offset (default 1)",
    "position_offset": "(default 0)",
    "process": "self-regulating (default) or integrating",
    "kp": "process gain, PV units per % OP",
    "delay_s": "process dead time, s (default 0)",
    "window_s": "analysis window, s (default 7200)",
    "result_address": "first result register (default: assigned)",
    "result_unit_id": "result unit id (default: modbus_server.unit_id)",
    "unit": "plant unit (area): the plant view groups loops of one unit only (default: "
            "none)",
    "priority": "the plant's weight of the loop in the list of valves to check, worst "
                "first: its suspicion is multiplied by it (default 1)",
}
"""The columns of a tag list and what each holds (empty cell: the key's default)."""
REQUIRED_COLUMNS = ("name", "device", "op", "pv")
MAX_TAG_BYTES = 8 * 1024 * 1024
"""A tag list larger than this (8 MiB, as a config) is not read."""

# column -> (point or None, key in the loop / point mapping); "op"/"pv": the protocol's
# address key (a plugin's POINT_ADDRESS_KEY, "address" by default)
_TARGETS: dict[str, tuple[str | None, str]] = {
    "op": ("op", ""), "pv": ("pv", ""), "op_type": ("op", "type"), "pv_type": ("pv", "type"),
    "op_table": ("op", "table"), "pv_table": ("pv", "table"), "op_scale": ("op", "scale"),
    "op_offset": ("op", "offset"), "pv_scale": ("pv", "scale"), "pv_offset": ("pv", "offset"),
    "op_shared": ("op", "shared"), "pv_shared": ("pv", "shared"),
    "position": ("position", ""), "position_type": ("position", "type"),
    "position_table": ("position", "table"), "position_scale": ("position", "scale"),
    "position_offset": ("position", "offset"), "position_shared": ("position", "shared"),
}
_SHARED = {"type": ("op_type", "pv_type", "position_type"),
           "table": ("op_table", "pv_table", "position_table"),
           "shared": ("op_shared", "pv_shared", "position_shared")}


@dataclasses.dataclass
class TagRow:
    """One data row: its line in the file, its non-empty cells by column, and ``problems``
    (how many problem lines name it; set while the config is read)."""

    line: int
    cells: dict[str, str]
    problems: int = 0
    whole: bool = True  # as many cells as the header has columns (else not read further)


@dataclasses.dataclass
class TagTable:
    """A read tag list: ``source`` (the file as named in messages), the problems of the
    file itself (unreadable, bad header: ``file_problems``) and its rows."""

    source: str
    rows: list[TagRow]
    file_problems: list[str] = dataclasses.field(default_factory=list)
    columns: list[str] = dataclasses.field(default_factory=list)  # the header's, in order

    @property
    def bad_lines(self) -> list[int]:
        return [r.line for r in self.rows if r.problems]


def read_tag_file(path: str | Path, shown_as: str | None = None) -> TagTable:
    """Read a tag list; ``shown_as`` names it in messages (default: ``path``)."""
    source = shown_as or str(path)
    try:
        data = read_bytes(path, MAX_TAG_BYTES)  # a regular file, within a time limit
        if len(data) > MAX_TAG_BYTES:
            return TagTable(source, [], [f"{source}: larger than {MAX_TAG_BYTES:,} bytes, "
                                         "the most a tag list may have"])
        text = data.decode("utf-8-sig")  # a spreadsheet's BOM
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        return TagTable(source, [], [f"{source}: cannot read: {reason}"])
    return read_tag_text(text, source)


def read_tag_text(text: str, source: str) -> TagTable:
    lines = [(n, line) for n, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    table = TagTable(source, [])
    if not lines:
        table.file_problems.append(f"{source}: no header row (columns: "
                                   f"{', '.join(REQUIRED_COLUMNS)}, ...)")
        return table
    head_line, head = lines[0]
    delimiter = max(",;\t", key=head.count)
    header = [c.strip().lower() for c in next(csv.reader([head], delimiter=delimiter))]
    table.columns = list(dict.fromkeys(c for c in header if c in COLUMNS))
    where = f"{source}: line {head_line}"
    for col in dict.fromkeys(header):
        if col not in COLUMNS:
            table.file_problems.append(f"{where}: unknown column {col!r} (known: "
                                       f"{', '.join(COLUMNS)})")
        elif header.count(col) > 1:
            table.file_problems.append(f"{where}: column {col!r} appears twice")
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        table.file_problems.append(f"{where}: missing column(s) "
                                   f"{', '.join(map(repr, missing))}")
        return table
    for n, line in lines[1:]:
        cells = next(csv.reader([line], delimiter=delimiter))
        row = TagRow(n, {col: cell.strip() for col, cell in zip(header, cells, strict=False)
                         if col in COLUMNS and cell.strip()})
        if len(cells) != len(header):  # its cells would land in the wrong columns
            table.file_problems.append(_count_problem(
                source, n, row, cells=len(cells), columns=len(header), delimiter=delimiter))
            row.problems += 1
            row.whole = False
        table.rows.append(row)
    if not table.rows:
        table.file_problems.append(f"{source}: no rows below the header (line {head_line})")
    return table


def _count_problem(source: str, n: int, row: TagRow, *, cells: int, columns: int,
                   delimiter: str) -> str:
    """A row with a cell too few or too many: said as such, not by the symptoms of its
    cells read under the wrong columns."""
    name = row.cells.get("name")
    what = "a cell is missing" if cells < columns else "there is a cell too many"
    shown = {"\t": "a tab"}.get(delimiter, repr(delimiter))
    return (f"{source}: line {n} has {cells} cells, the header has {columns}" +
            (f" (loop {name})" if name else "") + f": {what}; make the row "
            f"one cell per column (leave a cell empty for a default; a cell holding "
            f"{shown} must be in quotes)")


def _scalar(text: str) -> Any:
    """A cell as YAML would read it: an integer, a number, else the text."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def loop_mapping(row: TagRow, protocol: str | None) -> dict[str, Any]:
    """The loop mapping a YAML config would hold for ``row`` (a device of ``protocol``)."""
    plugin = input_plugin(protocol or "")
    address_key = getattr(plugin, "POINT_ADDRESS_KEY", "address")
    loop: dict[str, Any] = {}
    cells = dict(row.cells)
    for shared, (op_col, pv_col, pos_col) in _SHARED.items():
        if shared in cells:
            value = cells.pop(shared)
            cells.setdefault(op_col, value)
            cells.setdefault(pv_col, value)
            if "position" in cells:  # a position's own keys only where it has an address
                cells.setdefault(pos_col, value)
    for col, cell in cells.items():
        point, key = _TARGETS.get(col, (None, col))
        value = cell if col in ("name", "device") else _scalar(cell)
        if point is None:
            loop[key] = value
        else:
            loop.setdefault(point, {})[key or address_key] = value
    return loop


class _RowProblems(Problems):
    """The problems of one row: keys read as the row's columns; counted on the row."""

    def __init__(self, shared: Problems, table: TagTable, row: TagRow) -> None:
        super().__init__(table.source)
        self.lines = shared.lines  # one list, in reading order
        self.row = row

    def column(self, key: str) -> str:
        point, _, sub = key.partition(".")
        if not sub:
            return key
        if sub in _SHARED and f"{point}_{sub}" not in self.row.cells:
            return sub  # the shared column (type, table), given or not
        return f"{point}_{sub}" if f"{point}_{sub}" in COLUMNS else point

    def add(self, where: str, key: str | None, message: str) -> None:
        for lead, text in (("missing required key '", "required, but empty"),
                           ("unknown key '", "not used by this device's protocol")):
            if key is None and message.startswith(lead):
                key, message = message[len(lead):].split("'", maxsplit=1)[0], text
        parts = [self.source, where] + ([f"column {self.column(key)!r}"] if key else [])
        line = ": ".join([*parts, message])
        if line not in self.lines[-2:]:  # `type`/`table`: once for both points
            self.lines.append(line)
            self.row.problems += 1


def tag_tables(top: Section) -> list[TagTable]:
    """The tag lists named by the config's ``loops_csv`` (a file or a list of files,
    relative to the config file's directory), read; [] without ``loops_csv``."""
    raw = top.opt("loops_csv", _table_list, [])
    if raw is MISSING:
        return []
    config = Path(top.problems.source)
    base = config.parent if config.is_file() else Path()
    tables: list[TagTable] = []
    for item in raw:
        if isinstance(item, TagTable):
            tables.append(item)
            continue
        path = Path(item).expanduser()
        shown = item if path.is_absolute() else str(base / path)
        tables.append(read_tag_file(path if path.is_absolute() else base / path, shown))
    return tables


def _table_list(value: Any) -> list[str | TagTable]:
    items = value if isinstance(value, list) else [value]
    if not items or not all(isinstance(v, TagTable) or (isinstance(v, str) and v.strip())
                            for v in items):
        raise TypeError("must be a file name or a non-empty list of file names")
    return items


def tag_entries(problems: Problems, tables: list[TagTable],
                protocols: Mapping[str, str]) -> Iterator[tuple[int, Any, Section]]:
    """``(index, name, section)`` for each row of ``tables``, as
    :func:`gateway.config.schema.entries` yields the loops of a YAML list; the file
    problems of each table go to ``problems``."""
    for table in tables:
        problems.lines.extend(table.file_problems)
        for i, row in enumerate(table.rows):
            if not row.whole:  # said by its file problem; its cells are not where they belong
                continue
            name = row.cells.get("name")
            where = f"line {row.line}" + (f": loop {name}" if name else "")
            mapping = loop_mapping(row, protocols.get(row.cells.get("device", "")))
            section = Section(_RowProblems(problems, table, row), where, mapping)
            section.origin = f"{os.path.basename(table.source)}: line {row.line}"
            yield i, name, section
