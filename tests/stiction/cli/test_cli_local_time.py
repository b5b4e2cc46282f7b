"""Exports in local time and the names historians give the time column (issue 38 item 9):
the spring clock change without `--tz` is named, not only `bad_data: too gappy`; Ignition's
`t_stamp` and PI DataLink's empty first header are found without `--time`; a manifest
carries `tz` (and `decimal`) per file."""

from __future__ import annotations

import datetime as dt
import json
import zoneinfo
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from stiction.cli import main
from stiction.scenarios import simulate

BERLIN = zoneinfo.ZoneInfo("Europe/Berlin")


@pytest.fixture(scope="module")
def loop() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    res = simulate("table4-case2", noise=0.02, seed=4)
    return res.t, res.op, res.pv


def _write(path: Path, header: Sequence[str], loop: tuple[np.ndarray, ...],
           stamp: Callable[[float], str], sep: str = ";") -> Path:
    t, op, pv = loop
    lines = [sep.join(header)] + [sep.join((stamp(float(a)), f"{b:.4f}", f"{c:.4f}"))
                                  for a, b, c in zip(t, op, pv, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["analyze", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory, loop: tuple[np.ndarray, ...]) -> Path:
    """The same numbers written plainly: t in seconds, ',' separated."""
    return _write(tmp_path_factory.mktemp("clean") / "clean.csv", ("t", "op", "pv"), loop,
                  lambda a: f"{a:g}", ",")


def _answer(got: dict) -> dict:
    return {k: v for k, v in got.items() if k != "warnings"}


def _berlin(start: dt.datetime) -> Callable[[float], str]:
    return lambda a: (start + dt.timedelta(seconds=a)).astimezone(BERLIN).strftime(
        "%Y-%m-%d %H:%M:%S")


SPRING = dt.datetime(2024, 3, 31, 0, 50, tzinfo=dt.UTC)  # 01:50 CET; at 01:00 UTC 03:00 CEST


def test_the_spring_clock_change_in_local_stamps_is_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: Path) -> None:
    """Local stamps without a zone jump from 01:59:59 to 03:00:00 at the start of summer
    time: read as UTC, an hour is missing. Before: `bad_data: too gappy`, no word of the
    clock (the autumn change, an hour back, was named). Now the reason and a warning name
    the hour skipped and --tz; with --tz the answer is the clean export's."""
    path = _write(tmp_path / "pi.csv", ("Time", "FIC101.OP", "FIC101.PV"), loop,
                  _berlin(SPRING))
    text = path.read_text()
    assert "2024-03-31 01:59:59" in text and "2024-03-31 02:" not in text
    argv = [str(path), "--op", "FIC101.OP", "--pv", "FIC101.PV"]
    got = _json(capsys, *argv)
    assert got["verdict"] == "bad_data"
    assert "the time stamps skip an hour from '2024-03-31 01:59:59' (line 601) to " \
        "'2024-03-31 03:00:00' (line 602): local time without --tz?" in got["reason"]
    assert any(w.startswith("the time stamps skip an hour from '2024-03-31 01:59:59'") and
               "Give --tz with the historian's zone" in w for w in got["warnings"])
    right = _json(capsys, *argv, "--tz", "Europe/Berlin")
    assert _answer(right) == _answer(_json(capsys, str(clean)))
    assert not any("skip an hour" in w for w in right["warnings"])


def test_a_gap_of_an_hour_at_noon_is_no_clock_change(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...]
        ) -> None:
    t, op, pv = loop
    keep = (t < 1000) | (t >= 4600)
    start = dt.datetime(2024, 3, 31, 11, 43, 20)  # the hour missing from 12:00:00
    path = _write(tmp_path / "gap.csv", ("Time", "op", "pv"), (t[keep], op[keep], pv[keep]),
                  lambda a: (start + dt.timedelta(seconds=a)).strftime("%Y-%m-%d %H:%M:%S"))
    got = _json(capsys, str(path))
    assert not any("skip an hour" in w for w in got["warnings"])


def test_ignitions_t_stamp_is_the_time(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       loop: tuple[np.ndarray, ...], clean: Path) -> None:
    """The README names Ignition's `t_stamp` (Unix milliseconds); it needed --time."""
    path = _write(tmp_path / "ignition.csv", ("t_stamp", "FIC101/OP", "FIC101/PV"), loop,
                  lambda a: str(1_709_272_800_000 + round(1000 * a)), ",")
    got = _json(capsys, str(path), "--op", "FIC101/OP", "--pv", "FIC101/PV")
    assert _answer(got) == _answer(_json(capsys, str(clean)))
    assert any("column 't_stamp' holds Unix time in milliseconds" in w for w in got["warnings"])


def test_pi_datalinks_empty_first_header_is_the_time(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: Path) -> None:
    """PI DataLink leaves the time column's header empty: `,FIC101.OP,FIC101.PV`."""
    start = dt.datetime(2024, 3, 1, 6, 0, 0)
    path = _write(tmp_path / "datalink.csv", ("", "FIC101.OP", "FIC101.PV"), loop,
                  lambda a: (start + dt.timedelta(seconds=a)).strftime("%d-%b-%Y %H:%M:%S"),
                  ",")
    got = _json(capsys, str(path), "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert _answer(got) == _answer(_json(capsys, str(clean)))
    assert "column 1 has no name (as PI DataLink leaves the time column's): read as the " \
        "time" in got["warnings"]


def test_a_manifest_carries_the_zone_and_the_decimal_mark_per_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: Path) -> None:
    """Two plants' exports in one manifest: one in Berlin's local time, one in Chicago's,
    each with its own `tz`; a row's `decimal` settles numbers that read two ways."""
    _write(tmp_path / "berlin.csv", ("Time", "op", "pv"), loop, _berlin(SPRING))
    chicago = zoneinfo.ZoneInfo("America/Chicago")
    fall = dt.datetime(2024, 11, 3, 6, 50, tzinfo=dt.UTC)  # 01:50 CDT: 01:00-02:00 twice
    _write(tmp_path / "chicago.csv", ("Time", "op", "pv"), loop,
           lambda a: (fall + dt.timedelta(seconds=a)).astimezone(chicago).strftime(
               "%m/%d/%Y %H:%M:%S"))
    t, op, pv = loop
    rows = [f"{a:g}\t{1000 * b:,.0f}\t{c:.4f}" for a, b, c in zip(t, op, pv, strict=True)]
    (tmp_path / "grouped.txt").write_text("t\top\tpv\n" + "\n".join(rows) + "\n")
    manifest = tmp_path / "loops.csv"
    manifest.write_text("file;tz;decimal\nberlin.csv;Europe/Berlin;\n"
                        "chicago.csv;America/Chicago;\ngrouped.txt;;.\nberlin.csv;Mars/Base;\n"
                        "grouped.txt;;x\n")
    assert main(["analyze", "--manifest", str(manifest), "--json", "--no-site"]) == 0
    got = json.loads(capsys.readouterr().out)
    want = _answer(_json(capsys, str(clean)))
    for row in got[:2]:
        assert _answer({k: v for k, v in row.items()
                        if k not in ("file", "loop", "rank", "suspicion")}) == want, row["file"]
    assert got[2]["verdict"] == "stiction"  # OP 50,015 read as 50015, as the row says
    assert got[2]["size"]["fd"] == pytest.approx(1000 * want["size"]["fd"], rel=0.01)
    assert got[3]["error"].startswith(f"{manifest}:5: column 'tz': unknown zone 'Mars/Base'")
    assert got[4]["error"] == f"{manifest}:6: column 'decimal': 'x' is not '.' or ','"
