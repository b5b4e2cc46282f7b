"""Golden config cases: ``tests/cases/<case>/gateway.yaml`` with ``expected.err`` or
``expected.registers``, all run by the one test below.

* ``expected.err``: the config is refused; the file holds every problem, in the order
  ``check-config`` prints them (the config's path written as ``gateway.yaml``, a tag list
  beside it by its name).
* ``expected.registers``: the config loads; its devices are ``protocol: memory`` ones. Every
  device is polled once per row of its ``values`` (a fake clock from Unix time 1.7e9, one
  poll period per round), one analysis round runs with ``gateway_fake_analyze`` (verdicts
  from the OP swing, so the case checks the register map, not the analysis), and the file
  holds each loop's result block as the Modbus result server serves it: a comment line
  with the decoded fields, then ``unit U address A LOOP:`` and the 20 registers.

``UPDATE_GOLDEN=1 python -m pytest tests/test_cases.py`` rewrites the expected files (then
read the diff before committing it).
"""

from __future__ import annotations

import asyncio
import math
import os
from pathlib import Path

import pytest
from memory_harness import FAKE, Harness

from gateway.config import load_config
from gateway.errors import ConfigError
from gateway.wire.results import decode_block

CASES = Path(__file__).resolve().parent / "cases"
NAMES = sorted(p.name for p in CASES.iterdir() if (p / "gateway.yaml").is_file())


def _err(path: Path) -> str:
    try:
        load_config(path)
    except ConfigError as exc:
        return "".join(line.replace(str(path), "gateway.yaml", 1)
                       .replace(f"{path.parent}{os.sep}", "") + "\n"  # its tag lists
                       for line in exc.problems)
    return "(no problem: the config loads)\n"


def _num(key: str, x: float) -> str:
    if math.isnan(x):
        return "nan"
    return str(int(x)) if key in ("code", "seq", "timestamp") else f"{x:.6g}"


def _registers(path: Path) -> str:
    config = load_config(path)
    h = Harness(config)
    rounds = max(len(d.options.values) for d in config.devices)
    asyncio.run(h.tick(rounds))
    h.analyse(FAKE)
    out = []
    for lp in config.loops:
        regs = h.block(lp.name)
        fields = decode_block(regs, config.modbus_server.word_order)
        decoded = " ".join(f"{k}={_num(k, v)}" for k, v in fields.items() if k != "reserved")
        out.append(f"# {decoded}\n")
        out.append(f"unit {h.results.unit_of(lp)} address {lp.result_address} {lp.name}: "
                   + " ".join(str(int(r)) for r in regs) + "\n")
    return "".join(out)


@pytest.mark.parametrize("case", NAMES)
def test_case(case: str) -> None:
    folder = CASES / case
    kinds = [k for k in ("expected.err", "expected.registers") if (folder / k).exists()]
    assert len(kinds) == 1, f"{case}: needs exactly one of expected.err, expected.registers"
    kind = kinds[0]
    got = _err(folder / "gateway.yaml") if kind == "expected.err" else \
        _registers(folder / "gateway.yaml")
    if os.environ.get("UPDATE_GOLDEN") == "1":
        (folder / kind).write_text(got)
    assert got == (folder / kind).read_text()


def test_every_case_is_run() -> None:
    """A folder without gateway.yaml would silently not be a case."""
    folders = sorted(p.name for p in CASES.iterdir() if p.is_dir())
    assert folders == NAMES
    assert len(NAMES) >= 10
