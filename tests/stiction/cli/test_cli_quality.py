"""What the historian says of each sample, and long exports (issue 38 item 10): a quality
column's bad samples are gaps, as the same stretch written "Bad" is (a PHD export's PV 0 at
`Confidence` 0 was analysed as data); a long export, `DateTime,TagName,Value` as Wonderware
writes it, is read as one column per tag, said so (it was refused)."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np
import pytest

from stiction.cli import main
from stiction.scenarios import simulate

START = dt.datetime(2024, 3, 1, 6, 0, 0)
HOURS = 4


@pytest.fixture(scope="module")
def loop() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    res = simulate("table4-case2", noise=0.02, seed=4, duration=HOURS * 3600.0)
    return res.t, res.op, res.pv


def _stamp(a: float) -> str:
    return (START + dt.timedelta(seconds=a)).strftime("%Y-%m-%d %H:%M:%S")


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _answer(got: dict) -> dict:
    return {k: v for k, v in got.items() if k != "warnings"}


LOST = slice(5400, 7200)  # half an hour: the transmitter lost, PV read 0


def test_a_phd_confidence_of_0_is_a_gap_like_bad(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    t, op, pv = loop
    lost = np.zeros(t.size, dtype=bool)
    lost[LOST] = True
    phd = tmp_path / "phd.csv"
    bad = tmp_path / "bad.csv"
    with phd.open("w") as a, bad.open("w") as b:
        a.write("Timestamp,FIC101.OP,FIC101.PV,Confidence\n")
        b.write("Timestamp,FIC101.OP,FIC101.PV\n")
        for ti, o, p, x in zip(t, op, pv, lost, strict=True):
            a.write(f"{_stamp(ti)},{o:.4f},{0.0 if x else p:.4f},{0 if x else 100}\n")
            b.write(f"{_stamp(ti)},{o:.4f},{'Bad' if x else f'{p:.4f}'}\n")
    argv = ["--op", "FIC101.OP", "--pv", "FIC101.PV"]
    want = _json(capsys, "analyze", str(bad), *argv)
    got = _json(capsys, "analyze", str(phd), *argv)
    assert _answer(got) == _answer(want)
    assert "column 'FIC101.PV': 1800 samples of bad quality treated as gaps (column " \
        "'Confidence': 1800 with confidence 0 or below (PHD: bad))" in got["warnings"]


def _long(path: Path, loop: tuple[np.ndarray, ...], tags: dict[str, np.ndarray],
          bad_rows: int = 0) -> Path:
    """Wonderware's long export: one row per tag and time, tags in turn at each time, with
    OPC's QualityDetail (192 good; 0 for the first ``bad_rows`` rows of the last tag)."""
    t = loop[0]
    with path.open("w") as fh:
        fh.write("DateTime,TagName,Value,QualityDetail\n")
        for i, ti in enumerate(t):
            for k, (tag, x) in enumerate(tags.items()):
                q = 0 if k == len(tags) - 1 and i < bad_rows else 192
                fh.write(f"{_stamp(ti)}.000,{tag},{x[i]:.4f},{q}\n")
    return path


def test_a_long_export_is_read_one_column_per_tag(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    t, op, pv = loop
    wide = tmp_path / "wide.csv"
    with wide.open("w") as fh:
        fh.write("Timestamp,FIC101.OP,FIC101.PV,FIC101.SP\n")
        fh.writelines(f"{_stamp(a)},{b:.4f},{c:.4f},50\n" for a, b, c in zip(t, op, pv,
                                                                            strict=True))
    path = _long(tmp_path / "long.csv", loop, {"FIC101.SP": np.full(t.size, 50.0),
                                               "FIC101.OP": op, "FIC101.PV": pv})
    argv = ["--op", "FIC101.OP", "--pv", "FIC101.PV", "--sp", "FIC101.SP"]
    want = _json(capsys, "analyze", str(wide), *argv)
    got = _json(capsys, "analyze", str(path), *argv)
    assert got["verdict"] == "stiction" and _answer(got) == _answer(want)
    assert "a long export (columns 'DateTime', 'TagName', 'Value': one row per tag and time): " \
        "read as one column per tag (3: FIC101.SP, FIC101.OP, FIC101.PV)" in got["warnings"]


def test_a_long_export_s_bad_quality_is_a_gap(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    _, op, pv = loop
    path = _long(tmp_path / "long.csv", loop, {"FIC101.OP": op, "FIC101.PV": pv},
                 bad_rows=600)
    got = _json(capsys, "analyze", str(path), "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "600 rows of bad quality read as gaps (column 'QualityDetail': 600 of OPC " \
        "quality below 64 (bad))" in got["warnings"]


def test_a_plant_long_export(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`stiction plant` of the simulator's plant written long: each loop as from the wide
    file the simulator wrote."""
    wide = tmp_path / "plant.csv"
    assert main(["simulate", "--plant", "sticky-feeds-two", "--duration", "3600", "-o",
                 str(wide)]) == 0
    capsys.readouterr()
    rows = [line.split(",") for line in wide.read_text().splitlines()]
    long = tmp_path / "long.csv"
    with long.open("w") as fh:
        fh.write("DateTime,TagName,Value\n")
        for r in rows[1:]:
            fh.writelines(f"{_stamp(float(r[0]))},{tag},{x}\n"
                          for tag, x in zip(rows[0][1:], r[1:], strict=True))
    want = _json(capsys, "plant", str(wide))
    got = _json(capsys, "plant", str(long))
    assert [(x["loop"], x["verdict"], x["confidence"]) for x in got["loops"]] == \
        [(x["loop"], x["verdict"], x["confidence"]) for x in want["loops"]]


@pytest.mark.parametrize(("name", "cells", "bad"), [
    ("Confidence", ["100", "0", "-1", "50", ""], [False, True, True, False, False]),
    ("Quality", ["192", "0", "64", "24", "216"], [False, True, False, True, False]),
    ("Quality", ["0", "1", "0", "16"], [False, True, False, True]),
    ("Quality", ["0", "2150891520", "1073741824", "-2147483648"], [False, True, False, True]),
    ("FIC101.PV Quality", ["Good", "Bad", "bad_NotConnected", "Uncertain"],
     [False, True, True, False]),
])
def test_each_quality(tmp_path: Path, name: str, cells: list[str], bad: list[bool]) -> None:
    path = tmp_path / "q.csv"
    path.write_text(f"t,FIC101.PV,{name}\n" + "".join(f"{i},1,{c}\n"
                                                     for i, c in enumerate(cells)))
    from stiction.cli import quality  # noqa: PLC0415 - new in issue 38
    from stiction.cli.historian import read_table  # noqa: PLC0415

    table = read_table(path)
    assert quality.of(table.header, 1) == 2
    assert list(quality.bad(table, 2)[0]) == bad
