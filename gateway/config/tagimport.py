"""``stiction-gateway import-tags``: a tag list (CSV) to the YAML of its loops.

Every row is read as the gateway reads ``loops_csv`` (:mod:`gateway.config.tags`), against
the devices of a base config (``--config``) when one is given: the rows with a problem
are reported, each problem naming its line, and left out; the good rows are written as
YAML loops, one per line. With a base config the output is the whole config (its sections,
``loops_csv`` dropped, its own loops first); without one, only the ``loops:`` list, the
devices taken to be OPC UA ones where an op/pv cell is a node id (holds ``=``, as in
``ns=2;s=FIC101.OP``) and Modbus ones otherwise.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError
from .load import parse_config
from .tags import TagTable, loop_mapping, read_tag_file

__all__ = ["ImportResult", "guessed_devices", "import_tags", "read_yaml"]


@dataclasses.dataclass(frozen=True)
class ImportResult:
    """``text``: the YAML written (None when nothing can be: ``problems`` are not only
    bad rows); ``problems`` every problem line; ``bad_lines`` the rows left out."""

    text: str | None
    problems: list[str]
    bad_lines: list[int]
    loops: int  # rows written


def import_tags(csv_path: str | Path, config: str | Path | None = None) -> ImportResult:
    table = read_tag_file(csv_path)
    if config is not None:
        source = str(config)
        data = read_yaml(config)
        if not isinstance(data, dict):
            parse_config(data, source)  # raises ConfigError: what is wrong with it
        data.pop("loops_csv", None)
    else:
        data = {"devices": guessed_devices(table)}
        source = str(csv_path)
    protocols = {d.get("name"): d.get("protocol") for d in data.get("devices") or []
                 if isinstance(d, dict)}
    problems: list[str] = []
    try:
        parse_config({**data, "loops_csv": table}, source)
    except ConfigError as exc:
        problems = exc.problems
    bad = table.bad_lines
    if len(problems) > sum(r.problems for r in table.rows):  # not only bad rows
        return ImportResult(None, problems, bad, 0)
    loops = [loop_mapping(r, protocols.get(r.cells.get("device"))) for r in table.rows
             if not r.problems]
    if config is not None:
        data["loops"] = list(data.get("loops") or []) + loops
        text = _dump(data)
    else:
        text = _dump({"loops": loops})
    return ImportResult(text, problems, bad, len(loops))


def read_yaml(path: str | Path) -> Any:
    try:
        return yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    except yaml.YAMLError as exc:
        raise ConfigError([f"{path}: invalid YAML: {str(exc).replace(chr(10), ' ')}"]) from None


def guessed_devices(table: TagTable) -> list[dict[str, Any]]:
    modbus: dict[str, bool] = {}  # device -> no op/pv cell looks like a node id
    for row in table.rows:
        name = row.cells.get("device")
        if name:
            node = any("=" in row.cells.get(c, "") for c in ("op", "pv", "position"))
            modbus[name] = modbus.get(name, True) and not node
    return [{"name": n, "protocol": "modbus", "host": "localhost"} if m else
            {"name": n, "protocol": "opcua", "endpoint": "opc.tcp://localhost:4840"}
            for n, m in modbus.items()]


def _dump(data: dict[str, Any]) -> str:
    """Sections as YAML blocks, with ``loops`` one flow mapping per line."""
    loops = data.pop("loops", [])
    head = yaml.safe_dump(data, sort_keys=False, default_flow_style=None) if data else ""
    lines = [yaml.safe_dump(lp, default_flow_style=True, sort_keys=False,
                            width=1 << 16).strip() for lp in loops]
    return head + "loops:\n" + "".join(f"- {line}\n" for line in lines)
