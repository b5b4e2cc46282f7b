"""The verdict history's file is untrusted input, like the state file: whatever it holds, the
gateway starts (a bad file set aside, the history afresh), and what it loads has been
checked field by field."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import pytest
from memory_harness import Harness, mconfig, mloop, wiggle

from gateway.config import parse_config
from gateway.core.findings import FindingsBook
from gateway.inputs.memory import memory_device
from gateway.outputs.verdicts import VerdictFile
from gateway.outputs.verdicts.history import HistoryError, read_history, write_history

GOOD = {"A": {"days": ["2024-03-01", "2024-03-02"], "verdicts": ["no_stiction", "stiction"],
              "t": 1709400000.0, "verdict": "stiction"}}


def _doc(loops: Any, **top: Any) -> str:
    return json.dumps({"format": "stiction-gateway-verdicts", "version": 1, "saved": 1e9,
                       "loops": loops, **top})


def test_round_trip(tmp_path: Path) -> None:
    p = tmp_path / "gw.verdicts"
    write_history(p, GOOD, 1e9)
    assert read_history(p, max_loops=10) == GOOD
    assert not list(tmp_path.glob(".gw.verdicts.tmp-*"))


@pytest.mark.parametrize(("text", "kind", "why"), [
    ("PK\x03\x04 garbage", "corrupt", "not readable JSON"),
    ("[" * 100_000 + "]" * 100_000, "corrupt", "not readable JSON"),
    (json.dumps({"format": "stiction-gateway-state"}), "foreign", "not a stiction-gateway"),
    (_doc(GOOD, version=2), "foreign", "version 2"),
    (_doc(GOOD, saved="yesterday"), "corrupt", "saved: str where a number belongs"),
    (_doc({"A": {**GOOD["A"], "t": True}}), "corrupt", "bool where a number belongs"),
    (_doc({"A": {**GOOD["A"], "t": 1e300}}), "corrupt", "not a Unix time"),
    (_doc({"A": {**GOOD["A"], "verdict": "evil"}}), "corrupt", "not one of"),
    (_doc({"A": {**GOOD["A"], "days": ["2024-03-02", "2024-03-01"]}}), "corrupt",
     "not a date after the one before"),
    (_doc({"A": {**GOOD["A"], "days": ["2024-3-1", "2024-03-02"]}}), "corrupt",
     "not a date after"),
    (_doc({"A": {**GOOD["A"], "verdicts": ["stiction"]}}), "corrupt", "as many of each"),
    (_doc({"A": {**GOOD["A"], "extra": 1}}), "corrupt", "fields other than"),
    (_doc({"x" * 2000: GOOD["A"]}), "corrupt", "a loop name"),
    (_doc({f"L{k}": GOOD["A"] for k in range(50)}), "corrupt", "more than 20"),
    (_doc([1, 2, 3]), "corrupt", "loops: not a mapping"),
])
def test_a_bad_file_is_refused_naming_why(tmp_path: Path, text: str, kind: str,
                                          why: str) -> None:
    p = tmp_path / "gw.verdicts"
    p.write_text(text)
    with pytest.raises(HistoryError, match=why) as info:
        read_history(p, max_loops=20)
    assert info.value.kind == kind


def test_a_file_larger_than_the_config_can_need_is_not_read(tmp_path: Path) -> None:
    p = tmp_path / "gw.verdicts"
    p.write_bytes(b" " * (1024 * 1024 + 64 * 1000 * 2000))
    with pytest.raises(HistoryError, match="more than the"):
        read_history(p, max_loops=1)


def test_the_sink_sets_a_bad_file_aside_and_writes_a_good_one(tmp_path: Path) -> None:
    state = tmp_path / "gw.state"
    (tmp_path / "gw.verdicts").write_text(_doc({"A": {**GOOD["A"], "verdict": "evil"}}))
    raw = mconfig([memory_device("plc", wiggle(50, 2), poll_interval_s=0.05)],
                  [mloop("A", "plc", 0, 0)], state_file=str(state))
    h = Harness(parse_config(raw, "t"))
    book = FindingsBook()
    sink = VerdictFile(h.runtime.binding(), book, wall=lambda: h.time.wall)

    async def go() -> None:
        await sink.start()
        book.record("A", h.time.wall, "stiction")
        await sink.stop()

    asyncio.run(go())
    assert sink.set_aside is not None and sink.set_aside.name.startswith("gw.verdicts.corrupt-")
    assert read_history(tmp_path / "gw.verdicts", max_loops=5)["A"]["verdict"] == "stiction"
