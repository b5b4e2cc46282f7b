"""`stiction analyze --csv` writes a spreadsheet's CSV (issue 38 item 7): a cell that a
spreadsheet would evaluate (=, +, -, @, tab, CR first) is written as text, never as a live
formula; numbers, negative ones too, stay numbers."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from detector_fixtures import write_loop_csv

from stiction.cli import main

FORMULAS = ('=HYPERLINK("http://example.com/x","click")', "@SUM(1+1)", "+cmd|' /C calc'!A0",
            "-2+3")


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8-sig", newline="") as fh:
        return list(csv.DictReader(fh))


def test_a_manifest_cell_is_never_a_live_formula(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 38 item 7: a manifest row whose file is `=HYPERLINK(...)` was written as that
    formula into the `file` and `error` cells, live in the spreadsheet that opens it."""
    write_loop_csv(tmp_path)  # loop.csv: a sticky loop
    monkeypatch.chdir(tmp_path)  # the manifest's folder is '.': its cells start the labels
    (tmp_path / "loops.csv").write_text(
        "file\nloop.csv\n" + "".join(f'"{f.replace(chr(34), chr(34) * 2)}"\n' for f in FORMULAS),
        newline="")
    out = tmp_path / "unit.csv"
    assert main(["analyze", "--manifest", "loops.csv", "--json", "--csv", str(out)]) == 0
    objs = json.loads(capsys.readouterr().out)
    rows = _rows(out)
    assert len(rows) == len(objs) == 1 + len(FORMULAS)
    for obj, row in zip(objs[1:], rows[1:], strict=True):
        assert obj["file"][0] in "=+-@"  # the label as the manifest wrote it
        for key in ("file", "error"):
            assert row[key] == "'" + obj[key], (key, row[key])
    good = rows[0]
    assert good["verdict"] == "stiction"
    negative = [k for k, v in objs[0]["weighed"].items() if v < 0]
    assert negative  # some part weighed against stiction: a negative number
    for key in negative:  # written as a number, not as text
        assert float(good[f"weighed.{key}"]) == objs[0]["weighed"][key]
        assert good[f"weighed.{key}"].startswith("-")


@pytest.mark.parametrize(("text", "written"), [
    ("=1+1", "'=1+1"), ("+1+1", "'+1+1"), ("-1+1", "'-1+1"), ("@A1", "'@A1"),
    ("\t=1", "'\t=1"), ("\r=1", "'\r=1"), ("-inf", "'-inf"),
    ("-0.25", "-0.25"), ("+3", "+3"), ("-1e-05", "-1e-05"), ("12", "12"),
    ("loop.csv", "loop.csv"), ("", ""),
])
def test_each_cell(text: str, written: str) -> None:
    from stiction.cli.batch import spreadsheet_text  # noqa: PLC0415 - new in issue 38

    assert spreadsheet_text(text) == written
