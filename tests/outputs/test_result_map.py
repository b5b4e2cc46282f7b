"""``stiction-gateway result-map`` (issue 16): every loop's unit id, registers, types and
meanings, made from wire.results.LAYOUT; the table of docs/modbus-map.md is the same layout;
and what the CSV says is what mbpoll reads from a running gateway."""

from __future__ import annotations

import asyncio
import csv
import io
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from deploy_support import require_tool
from gateway_helpers import run

from gateway.config import load_config, parse_config
from gateway.core.plantview import PlantGroup, PlantView
from gateway.outputs.modbus_server.resultmap import COLUMNS, READ_WITH, layout_markdown, map_rows
from gateway.runtime.gateway import Gateway
from gateway.wire.results import LAYOUT, VERDICT_CODES, block_values
from stiction import Assessment, Verdict

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "gateway.cli"]
STICKY = Assessment(Verdict.STICTION, "test", oscillating=True, period_s=228.5,
                    stiction_index=0.93, fd=0.27, fs=0.30, jump=0.03, fd_op=27.0, fs_op=30.0,
                    cycles_used=6, confidence=0.91)


def config_yaml(word_order: str) -> dict[str, object]:
    return {
        "gateway": {"analysis_interval_s": 1e6},
        "metrics": {"listen": "127.0.0.1:0"},
        "modbus_server": {"listen": "127.0.0.1:0", "word_order": word_order},
        "devices": [{"name": "bench", "protocol": "memory", "repeat": True,
                     "values": [[50.0, 20.0, 51.0, 21.0], [52.0, 20.5, 49.0, 20.5]]}],
        "loops": [{"name": "FIC101", "device": "bench", "op": {"column": 0},
                   "pv": {"column": 1}, "window_s": 60},
                  {"name": "FIC102", "device": "bench", "op": {"column": 2},
                   "pv": {"column": 3}, "window_s": 60, "kp": 1.0, "result_unit_id": 2,
                   "result_address": 300}],
    }


def test_each_register_says_holding_or_input() -> None:
    """Issue 32 item 10: the map did not say input or holding registers. Both hold the same
    values; each row gives the register's 1-based reference in each table."""
    c = parse_config(config_yaml("big"), "gw.yaml")
    row = next(r for r in map_rows(c) if r.loop == "FIC102" and r.field == "fd_percent")
    assert (row.register, row.holding, row.input) == (304, 400305, 300305)
    assert dict(zip(COLUMNS, row.cells(), strict=True))["holding"] == "400305"
    assert "holding registers (function code 3" in READ_WITH
    assert "input registers (function code 4" in READ_WITH


def test_rows_follow_the_layout() -> None:
    c = parse_config(config_yaml("little"), "gw.yaml")
    rows = list(map_rows(c))
    assert len(rows) == 2 * len(LAYOUT)
    by_loop = {name: [r for r in rows if r.loop == name] for name in ("FIC101", "FIC102")}
    for name, unit, first in (("FIC101", 1, 0), ("FIC102", 2, 300)):
        for f, r in zip(LAYOUT, by_loop[name], strict=True):
            assert (r.unit_id, r.register, r.offset, r.field, r.type) == (
                unit, first + f.offset, f.offset, f.name, f.type_name)
            assert r.word_order == ("little" if f.width == 2 else "-")
            assert (r.unit, r.meaning, r.scale) == (f.unit, f.meaning, f.scale)
            assert r.meaning and r.unit
    assert [r.loop for r in map_rows(c, ["FIC102"])] == ["FIC102"] * len(LAYOUT)


def test_the_docs_table_is_the_layout() -> None:
    """docs/modbus-map.md shows the block as LAYOUT defines it (regenerate the table with
    gateway.outputs.modbus_server.resultmap.layout_markdown() when a field is added)."""
    doc = (ROOT / "docs" / "modbus-map.md").read_text()
    assert layout_markdown() in doc
    assert all(f"{c} " in LAYOUT[0].meaning for c in VERDICT_CODES.values())


def test_result_map_cli_table_and_csv(tmp_path: Path) -> None:
    path = tmp_path / "gw.yaml"
    path.write_text(yaml.safe_dump(config_yaml("big")))
    res = subprocess.run([*CLI, "result-map", "--config", str(path), "--csv"],
                         capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert list(rows[0]) == list(COLUMNS)
    want = [r.cells() for r in map_rows(load_config(path))]
    assert [list(r.values()) for r in rows] == want
    res = subprocess.run([*CLI, "result-map", "--config", str(path), "FIC102"],
                         capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0] == READ_WITH
    assert lines[1].split() == list(COLUMNS)
    assert lines[2].split()[:8] == ["FIC102", "2", "300", "400301", "300301", "0", "code",
                                    "uint16"]
    assert len(lines) == 2 + len(LAYOUT)
    res = subprocess.run([*CLI, "result-map", "--config", str(path), "FIC999"],
                         capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 2
    assert res.stderr == f"{path}: no loop 'FIC999'\n"


MBPOLL_TYPES = {"uint16": "3", "float32": "3:float", "uint32": "3:int",
                "uint8 (high byte)": "3", "uint8 (low byte)": "3"}


def mbpoll_read(mbpoll: str, port: int, row: dict[str, str]) -> float:
    cmd = [mbpoll, "-m", "tcp", "-p", str(port), "-a", row["unit_id"], "-0", "-r",
           row["register"], "-c", "1", "-t", MBPOLL_TYPES[row["type"]], "-1",
           *(["-B"] if row["word_order"] == "big" else []), "127.0.0.1"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=15, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    values = re.findall(r"^\[\d+\]:\s+(\S+)", r.stdout, re.M)
    assert len(values) == 1, r.stdout
    if row["type"].startswith("uint8"):  # one byte of the register
        reg = int(values[0])
        return float(reg >> 8 if "high" in row["type"] else reg & 0xFF)
    return float(values[0])


@pytest.mark.e2e
@pytest.mark.parametrize("word_order", ["big", "little"])
def test_result_map_csv_is_what_mbpoll_reads(tmp_path: Path, word_order: str) -> None:
    """For one loop (on unit id 2, with every field set), each CSV row read with mbpoll at
    its unit id, register, type and word order gives the field's value."""
    mbpoll = require_tool("mbpoll", "mbpoll")
    path = tmp_path / "gw.yaml"
    path.write_text(yaml.safe_dump(config_yaml(word_order)))
    res = subprocess.run([*CLI, "result-map", "--config", str(path), "--csv", "FIC102"],
                         capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert {r["field"] for r in rows} == {f.name for f in LAYOUT}

    async def go() -> tuple[dict[str, float], dict[str, float]]:
        async with Gateway(load_config(path), serve_http=False) as gw:
            i = gw.store.index["FIC102"]
            result = gw.store.set_result(i, STICKY, t=1_700_000_123.0, window_fill=0.75,
                                         samples=60)
            gw.store.set_plant(PlantView((PlantGroup(4, 230.0, "FIC102", ("FIC102", "X")),),
                                         {"FIC102": (4, "source")}))
            plant = gw.store.plant_registers(i)
            assert plant == (4, 1, i + 1)
            want = block_values(result, VERDICT_CODES[Verdict.STICTION], plant)
            got = {}
            for row in rows:
                got[row["field"]] = float(row["scale"]) * await asyncio.to_thread(
                    mbpoll_read, mbpoll, gw.result_port, row)
            return want, got

    want, got = run(go(), 60)
    assert set(got) == set(want)
    for field, value in want.items():
        if math.isnan(value):
            assert math.isnan(got[field]), field
        else:  # float32 in the registers, mbpoll prints 6 significant digits
            assert got[field] == pytest.approx(value, rel=1e-5), field
    assert got["code"] == 4 and got["timestamp"] == 1_700_000_123
