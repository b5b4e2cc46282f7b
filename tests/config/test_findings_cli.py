"""`check-config` reports the findings file's problems but never fails on them (the systemd
unit runs it before every start, and run skips a bad row); `stiction-gateway findings`
prints the agreement table and exits 2 when the file has problems (for a plant's CI)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
import yaml

from gateway.cli import main
from gateway.outputs.verdicts.history import write_history

DAY = dt.date(2024, 3, 4)


def _config(tmp_path: Path) -> Path:
    raw = {"devices": [{"name": "plc", "protocol": "modbus", "host": "127.0.0.1"}],
           "loops": [{"name": n, "device": "plc", "op": {"address": 4 * k, "type": "float32"},
                      "pv": {"address": 4 * k + 2, "type": "float32"}}
                     for k, n in enumerate(("FIC101", "LIC201", "TIC301"))],
           "gateway": {"state_file": str(tmp_path / "gw.state")},
           "findings": "findings.csv"}
    path = tmp_path / "gw.yaml"
    path.write_text(yaml.safe_dump(raw))
    (tmp_path / "findings.csv").write_text(
        "loop,date,finding,fd,fs,by,note\n"
        f"FIC101,{DAY},stiction,2.5,3,J. Doe,packing tightened\n"
        f"LIC201,{DAY},ok,,,J. Doe,cycle from the feed\n"
        f"TIC301,{DAY},stiction,,,,\n"
        f"FIC999,{DAY},ok,,,,\n")
    return path


def test_check_config_reports_findings_problems_but_passes(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = _config(tmp_path)
    assert main(["check-config", str(cfg)]) == 0
    out, err = capsys.readouterr()
    assert f"{tmp_path / 'findings.csv'}: 3 finding(s), 1 bad row(s) skipped by run" in out
    assert err.splitlines() == [f"{tmp_path / 'findings.csv'}: line 5: loop FIC999: column "
                                "'loop': no loop 'FIC999' in the config"]
    (tmp_path / "findings.csv").unlink()
    assert main(["check-config", str(cfg)]) == 0  # a missing file never stops a start
    assert "not read: run starts without findings" in capsys.readouterr().err


def test_findings_command_prints_the_agreement(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    cfg = _config(tmp_path)
    t = dt.datetime.combine(DAY - dt.timedelta(days=2), dt.time(9)).timestamp()
    write_history(tmp_path / "gw.verdicts", {
        "FIC101": {"days": [str(DAY - dt.timedelta(days=2))], "verdicts": ["stiction"],
                   "t": t, "verdict": "stiction"},
        "LIC201": {"days": [str(DAY - dt.timedelta(days=2))], "verdicts": ["stiction"],
                   "t": t, "verdict": "stiction"}}, t)
    assert main(["findings", "--config", str(cfg)]) == 2  # the bad row: for CI
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert lines[0].endswith(f"3 finding(s) of 3 loop(s); verdict history "
                             f"{tmp_path / 'gw.verdicts'} (2 loops)")
    table = "\n".join(lines[2:6])
    assert table.split("\n")[1].split() == ["stiction", "1", "0", "1", "0", "2"]
    assert table.split("\n")[2].split() == ["unknown", "1", "0", "0", "0", "1"]
    assert ("`stiction` calls the crew found sticking: 1 of 2 (50 %); sticking valves the "
            "gateway had called: 1 of 2 (50 %)") in out
    assert f"FIC101           {DAY} stiction    2.5     3 stiction" in out
    assert "FIC999" in err
    (tmp_path / "findings.csv").write_text(f"loop,date,finding\nFIC101,{DAY},ok\n")
    assert main(["findings", "--config", str(cfg)]) == 0
