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
    # TIC301's sticking valve was found where no verdict existed that day: not a miss
    assert ("`stiction` calls the crew found sticking: 1 of 2 (50 %); sticking valves the "
            "gateway had called: 1 of 1 (100 %), and 1 found where no verdict existed that "
            "day (before the gateway's history of the loop: not counted)") in out
    assert f"FIC101           {DAY} stiction    2.5     3 stiction" in out
    assert "FIC999" in err
    (tmp_path / "findings.csv").write_text(f"loop,date,finding\nFIC101,{DAY},ok\n")
    assert main(["findings", "--config", str(cfg)]) == 0


def test_no_verdict_is_no_miss_and_each_finding_has_its_before_and_after(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 38 item 12: one sticking valve found before the gateway had judged its loop
    read "0 of 1 (0 %)"; a step test's dead band went into fd; no before/after a repair."""
    cfg = _config(tmp_path)
    day = dt.date.today() - dt.timedelta(days=20)
    (tmp_path / "findings.csv").write_text(
        "loop,date,finding,deadband,resolution,by,note\n"
        f"FIC101,{day},stiction,4.0,2.0,J. Doe,step test; packing replaced\n")
    assert main(["findings", "--config", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert ("`stiction` calls the crew found sticking: no `stiction` verdict on a finding's "
            "day; sticking valves the gateway had called: no verdict existed on their day "
            "(1 found before the gateway's history of the loop)") in out
    assert "0 of 1" not in out
    # fd and fs worked out from the step test: fs = (4 + 2) / 2, fd = (4 - 2) / 2
    assert f"FIC101           {day} stiction      1     3 unknown" in out
    # the history: stiction from 30 days ago, cleared the day after the repair, back later
    noon = dt.time(12)
    ts = [dt.datetime.combine(day + dt.timedelta(days=k), noon).timestamp()
          for k in (-10, 1, 12)]
    write_history(tmp_path / "gw.verdicts", {"FIC101": {
        "days": [str(day - dt.timedelta(days=10)), str(day + dt.timedelta(days=2)),
                 str(day + dt.timedelta(days=13))],
        "verdicts": ["stiction", "no_stiction", "stiction"], "t": ts[-1],
        "verdict": "stiction"}}, ts[-1])
    assert main(["findings", "--config", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert ("`stiction` calls the crew found sticking: 1 of 1 (100 %); sticking valves the "
            "gateway had called: 1 of 1 (100 %)") in out
    after = [ln for ln in out.splitlines() if ln.startswith("FIC101") and "now" in ln]
    assert after == [f"FIC101           {day} stiction  stiction             stiction the next "
                     f"day, no_stiction from {day + dt.timedelta(days=2)}, stiction from "
                     f"{day + dt.timedelta(days=13)}; now stiction (stiction came back)"]


def test_a_dead_band_written_in_fd_is_named(tmp_path: Path) -> None:
    from gateway.config.findings import read_findings  # noqa: PLC0415

    p = tmp_path / "f.csv"
    p.write_text("loop,date,finding,fd,fs,deadband,resolution\n"
                 f"FIC101,{DAY},stiction,3.9,,3.9,\n"  # the dead band copied into fd
                 f"LIC201,{DAY},stiction,3.9,4.1,3.9,\n"  # fd + fs is not the dead band
                 f"TIC301,{DAY},stiction,,,4.02,2.05\n")  # as valve-test prints them
    got = read_findings(p, ["FIC101", "LIC201", "TIC301"], today=DAY, shown_as="f.csv")
    hint = ("a step test's dead band is fs + fd and its resolution fs - fd: write them in "
            "'deadband' and 'resolution' and leave fd and fs empty, they are worked out")
    assert got.problems == (
        f"f.csv: line 2: loop FIC101: column 'fd': 3.9 exceeds fs 0 (fd is never above fs) "
        f"({hint})",
        f"f.csv: line 3: loop LIC201: column 'fd': fd 3.9 + fs 4.1 = 8 is not the dead band "
        f"3.9 ({hint})")
    (tic,) = got.findings
    assert (tic.fs, tic.fd) == pytest.approx((3.035, 0.985))
