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
        "column (an empty cell for an empty value; a cell holding the delimiter or a line "
        "break in double quotes)",
        "findings.csv: line 10: column 'loop': required, but empty",
        "findings.csv: line 11: loop FIC101: repeats line 2")
    assert got.readable  # type: ignore[attr-defined]


@pytest.mark.parametrize(("text", "problem"), [
    ("", "findings.csv: no header row (columns: loop, date, finding, fd, fs, deadband, "
         "resolution, by, note)"),
    ("loop,when,finding\nFIC101,2024-03-05,ok\n",
     "findings.csv: line 1: unknown column 'when' (known: loop, date, finding, fd, fs, "
     "deadband, resolution, by, "
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
    p = tmp_path / "garbage.csv"  # 0x81 and 0x8d are neither UTF-8 nor Windows-1252
    p.write_bytes(b"loop,date,finding\nFIC101,2024-03-05,ok\nTIC301,2024-03-05,ok\x81\x8d\n")
    got = read_findings(p, LOOPS, today=TODAY)
    assert not got.readable and got.problems == (f"{p}: line 3: neither UTF-8 nor "
                                                 "Windows-1252 (save the file as CSV UTF-8)",)


# issue 35 item 8: rows as a spreadsheet saves them, each read, none lost
def test_a_note_over_several_lines_is_one_cell_and_the_next_row_is_read(
        tmp_path: Path) -> None:
    got = _read(tmp_path, 'loop,date,finding,fd,fs,by,note\r\n'
                          'FIC101,2024-03-05,stiction,2.5,3.1,J. Doe,"packing tightened\n'
                          '# not a comment: the note goes on\n'
                          '\n'
                          'positioner recalibrated, see WO 4711"\r\n'
                          '# a comment between rows\r\n'
                          'TIC301,2024-03-07,ok,,,J. Doe,cycle from the steam header\r\n')
    assert got.problems == ()  # type: ignore[attr-defined]
    fic, tic = got.findings  # type: ignore[attr-defined]
    assert (fic.line, tic.line) == (2, 7)
    assert fic.note == ("packing tightened # not a comment: the note goes on  positioner "
                        "recalibrated, see WO 4711")
    assert tic.note == "cycle from the steam header"


@pytest.mark.parametrize("head", ["sep=;\r\n", '"sep=;"\n', "# exported\nSEP=;\n"])
def test_an_excel_sep_line_names_the_delimiter(tmp_path: Path, head: str) -> None:
    got = _read(tmp_path, f"{head}loop;date;finding;fd;fs;by;note\n"
                          "FIC101;05.03.2024;stiction;2,5;3,1;J. Doe;tightened, retested\n")
    assert got.problems == ()  # type: ignore[attr-defined]
    (fic,) = got.findings  # type: ignore[attr-defined]
    assert (fic.date, fic.fd, fic.fs, fic.note) == (dt.date(2024, 3, 5), 2.5, 3.1,
                                                   "tightened, retested")


def test_windows_1252_and_utf16_text_is_read(tmp_path: Path) -> None:
    text = "loop;date;finding;fd;fs;by;note\nFIC101;05.03.2024;ok;;;J. Müller;Ventil gängig, 5 °C\n"
    for name, data in (("cp1252.csv", text.encode("cp1252")),
                       ("utf16.csv", text.encode("utf-16")),
                       ("mixed.csv", text.encode("utf-8") + "LIC201;06.03.2024;ok;;;Jörg;\n"
                        .encode("cp1252"))):
        p = tmp_path / name
        p.write_bytes(data)
        got = read_findings(p, LOOPS, today=TODAY)
        assert got.problems == (), name
        assert got.findings[0].by == "J. Müller" and got.findings[0].note.endswith("5 °C")
    assert [f.by for f in got.findings] == ["J. Müller", "Jörg"]


def test_empty_columns_after_the_last_are_ignored(tmp_path: Path) -> None:
    got = _read(tmp_path, "loop,date,finding,fd,fs,by,note,,\n"
                          "FIC101,2024-03-05,stiction,2.5,3.1,J. Doe,tightened,,\n"
                          "TIC301,2024-03-07,ok,,,J. Doe,steam header\n"
                          "LIC201,2024-03-07,ok,,,J. Doe,feed,,spilled\n")
    assert [f.loop for f in got.findings] == ["FIC101", "TIC301"]  # type: ignore[attr-defined]
    assert got.problems == ("findings.csv: line 4 has 9 cells, the header has 7: make the "  # type: ignore[attr-defined]
                            "row one cell per column (an empty cell for an empty value; a "
                            "cell holding the delimiter or a line break in double quotes)",)


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
