"""The engineer's findings file (``findings:`` in the config): every bad row named (file,
line, what is wrong) and skipped, never fatal; a file that cannot be read says so and is
not used; the config key itself never makes a config invalid, and configs without it load
unchanged."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
import yaml

from gateway.config import load_config, parse_config
from gateway.config.findings import Finding, read_findings, verdicts_path

TODAY = dt.date(2024, 3, 10)
LOOPS = ("FIC101", "LIC201", "TIC301")


def _read(tmp_path: Path, text: str, name: str = "findings.csv") -> object:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return read_findings(p, LOOPS, today=TODAY, shown_as=name)


def test_good_rows_in_any_column_order_case_and_delimiter(tmp_path: Path) -> None:
    got = _read(tmp_path, "\ufeff# kept under version control\n"
                          "Date;LOOP;Finding;fs;fd;by;note\n"
                          "2024-03-05;FIC101;stiction;3,1;2,5;J. Doe;packing tightened\n"
                          "\n"
                          "07.03.2024;TIC301;OK;;;;cycle from the steam header\n")
    assert got.readable and got.problems == ()  # type: ignore[attr-defined]
    assert got.findings == (  # type: ignore[attr-defined]
        Finding("FIC101", dt.date(2024, 3, 5), "stiction", 2.5, 3.1, "J. Doe",
                "packing tightened", 3),
        Finding("TIC301", dt.date(2024, 3, 7), "ok", None, None, "",
                "cycle from the steam header", 5))


def test_every_bad_row_is_named_and_skipped(tmp_path: Path) -> None:
    got = _read(tmp_path, "loop,date,finding,fd,fs,by,note\n"
                          "FIC101,2024-03-05,stiction,2.5,3.1,JD,ok row\n"
                          "FIC999,2024-03-05,stiction,,,,\n"
                          "LIC201,5 March,ok,,,,\n"
                          "LIC201,2024-03-05,stuck,,,,\n"
                          "LIC201,2024-03-05,stiction,3,2,,\n"
                          "LIC201,2024-03-05,stiction,abc,,,\n"
                          "LIC201,2030-01-01,ok,,,,\n"
                          "LIC201,2024-03-06,ok\n"
                          ",2024-03-06,ok,,,,\n"
                          "FIC101,2024-03-05,stiction,2.5,3.1,JD,ok row\n"
                          "TIC301,2024-03-08T14:00:00,deadband,1.2,,,\n")
    assert [f.line for f in got.findings] == [2, 12]  # type: ignore[attr-defined]
    assert got.findings[1].date == dt.date(2024, 3, 8)  # type: ignore[attr-defined]
    assert got.problems == (  # type: ignore[attr-defined]
        "findings.csv: line 3: loop FIC999: column 'loop': no loop 'FIC999' in the config",
        "findings.csv: line 4: loop LIC201: column 'date': '5 March' is not a date (write "
        "YYYY-MM-DD, e.g. 2024-03-10)",
        "findings.csv: line 5: loop LIC201: column 'finding': must be one of stiction, "
        "deadband, ok, other, was 'stuck'",
        "findings.csv: line 6: loop LIC201: column 'fd': 3 exceeds fs 2 (fd is never above fs)",
        "findings.csv: line 7: loop LIC201: column 'fd': must be a number of % of span (0 to "
        "100), was 'abc'",
        "findings.csv: line 8: loop LIC201: column 'date': 2030-01-01 is in the future",
        "findings.csv: line 9 has 3 cells, the header has 7: make the row one cell per "
        "column (an empty cell for an empty value)",
        "findings.csv: line 10: column 'loop': required, but empty",
        "findings.csv: line 11: loop FIC101: repeats line 2")
    assert got.readable  # type: ignore[attr-defined]


@pytest.mark.parametrize(("text", "problem"), [
    ("", "findings.csv: no header row (columns: loop, date, finding, fd, fs, by, note)"),
    ("loop,when,finding\nFIC101,2024-03-05,ok\n",
     "findings.csv: line 1: unknown column 'when' (known: loop, date, finding, fd, fs, by, "
     "note)"),
    ("loop,finding\nFIC101,ok\n", "findings.csv: line 1: missing column(s) 'date'"),
])
def test_a_file_without_a_usable_header_is_not_read(tmp_path: Path, text: str,
                                                    problem: str) -> None:
    got = _read(tmp_path, text)
    assert not got.readable and got.findings == ()  # type: ignore[attr-defined]
    assert problem in got.problems  # type: ignore[attr-defined]


def test_missing_and_undecodable_files_are_not_read(tmp_path: Path) -> None:
    got = read_findings(tmp_path / "nope.csv", LOOPS, today=TODAY)
    assert not got.readable and "cannot read" in got.problems[0]
    p = tmp_path / "latin.csv"
    p.write_bytes(b"loop,date,finding\nFIC101,2024-03-05,ok\nTIC301,2024-03-05,ok,\xb0\n")
    got = read_findings(p, LOOPS, today=TODAY)
    assert not got.readable and got.problems == (f"{p}: line 3: not UTF-8 (save the file "
                                                 "as UTF-8)",)


def test_the_config_key_names_a_file_beside_the_config(tmp_path: Path) -> None:
    cfg = tmp_path / "gw.yaml"
    raw = {"devices": [{"name": "plc", "protocol": "modbus", "host": "127.0.0.1"}],
           "loops": [{"name": "FIC101", "device": "plc",
                      "op": {"address": 0, "type": "float32"},
                      "pv": {"address": 2, "type": "float32"}}],
           "findings": "findings.csv", "gateway": {"state_file": "state/gw.state"}}
    cfg.write_text(yaml.safe_dump(raw))
    config = load_config(cfg)  # the file need not exist: run reads it, not the loader
    assert config.findings == str(tmp_path / "findings.csv")
    assert verdicts_path(config.gateway.state_file) == Path("state/gw.verdicts")
    assert verdicts_path("state/gw") == Path("state/gw.verdicts")
    del raw["findings"]
    assert parse_config(raw, "old.yaml").findings is None  # an old config: no findings
    raw["findings"] = 3
    with pytest.raises(Exception, match="key 'findings': must be a non-empty string"):
        parse_config(raw, "bad.yaml")
