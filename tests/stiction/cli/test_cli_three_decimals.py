"""Exports whose every number has three decimals (`57.123`), issue 38 item 5: each column's
decimal mark is told once from the whole file (linear in its cells, not in its columns
squared), and an OP column that reads inside its OP range one way and a thousand times
outside it the other is not ambiguous: a `;` export with `.` decimals is read (the release
before read it), as the same numbers written plainly."""

from __future__ import annotations

import csv
import datetime as dt
import json
from pathlib import Path

import numpy as np
import pytest

from stiction.cli import decimals, main
from stiction.scenarios import simulate

START = dt.datetime(2024, 3, 1, 6, 0, 0)
BOTH = r"[1-9]\d{0,2}\.\d{3}"


def _stamp(t: float) -> str:
    return (START + dt.timedelta(seconds=float(t))).isoformat(sep=" ")


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_a_semicolon_export_with_decimal_points_is_read(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The outsider's export: `Timestamp;FIC101.OP;FIC101.PV`, ISO stamps, every number
    `44.000`-like. Before: exit 2, "'44.000' reads as 44 ... or as 44000". Now: read with
    '.' (OP 44, not 44000 % of span), said so, and the answer is the plain CSV's."""
    res = simulate("table4-case2", noise=0.02, seed=4)
    op, pv = np.round(res.op, 3), np.round(res.pv, 3)
    assert min(op.min(), pv.min()) >= 1.0 and max(op.max(), pv.max()) < 100.0
    export = tmp_path / "fic101.csv"
    with export.open("w", newline="") as fh:
        w = csv.writer(fh, delimiter=";", lineterminator="\r\n")
        w.writerow(["Timestamp", "FIC101.OP", "FIC101.PV"])
        w.writerows([_stamp(t), f"{o:.3f}", f"{p:.3f}"] for t, o, p in zip(res.t, op, pv,
                                                                           strict=True))
    text = export.read_text().splitlines()[1].split(";")
    assert all(decimals.kind(c) == "both" for c in text[1:])  # no number tells
    plain = tmp_path / "plain.csv"
    np.savetxt(plain, np.column_stack([res.t, op, pv]), delimiter=",", header="t,op,pv",
               comments="", fmt=["%g", "%.3f", "%.3f"])
    want = _json(capsys, ["analyze", str(plain)])
    got = _json(capsys, ["analyze", str(export), "--op", "FIC101.OP", "--pv", "FIC101.PV"])
    assert got["verdict"] == want["verdict"] == "stiction"
    assert {k: v for k, v in got.items() if k != "warnings"} == \
        {k: v for k, v in want.items() if k != "warnings"}
    said = " ".join(got["warnings"])
    assert "column 'FIC101.OP': " in said and "outside the OP range 0-100" in said


def test_a_plant_export_of_three_decimals_is_read_as_written_plainly(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`stiction simulate --plant` rewritten `;`-separated with three decimals: every
    loop's verdict as of the file the simulator wrote; one warning says how, not one per
    column."""
    plain = tmp_path / "plant.csv"
    assert main(["simulate", "--plant", "sticky-feeds-two", "--duration", "3600", "-o",
                 str(plain)]) == 0
    capsys.readouterr()
    with plain.open(newline="") as fh:
        rows = list(csv.reader(fh))
    export = tmp_path / "plant3.csv"
    with export.open("w", newline="") as fh:
        w = csv.writer(fh, delimiter=";")
        w.writerow(["Timestamp", *rows[0][1:]])
        w.writerows([_stamp(float(r[0])), *(f"{float(c):.3f}" for c in r[1:])]
                    for r in rows[1:])
    rounded = tmp_path / "rounded.csv"  # the same numbers, plainly
    with rounded.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        w.writerows([r[0], *(f"{float(c):.3f}" for c in r[1:])] for r in rows[1:])
    want = _json(capsys, ["plant", str(rounded)])
    got = _json(capsys, ["plant", str(export)])
    assert [(x["loop"], x["verdict"], x["confidence"]) for x in got["loops"]] == \
        [(x["loop"], x["verdict"], x["confidence"]) for x in want["loops"]]
    assert [g["loops"] for g in got["groups"]] == [g["loops"] for g in want["groups"]]
    columns = [w for w in got["warnings"] if "decimal mark" in w]
    assert len(columns) <= 2, columns  # said once for the many columns read so


def test_each_column_is_told_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Before, every column whose numbers all read two ways tallied every other column
    again: 40 columns x 300 rows judged some 480,000 cells one by one (250 loops x 7,200
    rows: 935 s). Now the cells that read two ways are found in bulk, and the cells judged
    one by one are only those that tell: none here, however many columns and rows."""
    rng = np.random.default_rng(0)
    header = ["t"] + [f"L{k}.{s}" for k in range(20) for s in ("OP", "PV")]
    path = tmp_path / "wide.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows([str(i), *(f"{x:.3f}" for x in rng.uniform(10.0, 90.0, 40))]
                    for i in range(300))
    judged = []
    real = decimals.kind

    def kind(cell: str) -> str | None:
        judged.append(cell)
        return real(cell)

    monkeypatch.setattr(decimals, "kind", kind)
    got = _json(capsys, ["plant", str(path)])
    assert len(got["loops"]) == 20
    assert len(judged) < 40, len(judged)
