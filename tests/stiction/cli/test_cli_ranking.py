"""`stiction analyze` of many files, worst first (issue 39): the rank column, --sort file,
--top, the manifest's priority and loop, --findings (the unit's own calibration) and
--report (the page lists the loops in --json's order, on the shared plant records)."""

from __future__ import annotations

import csv
import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lab.sources import records
from stiction.cli import main
from stiction.scenarios import scenario, simulate

# (file stem, scenario, seed): confidences 0.99-1.0 (table4), 0.92 and 0.96 (table5-case2),
# under 0.4 (the others); table4-case1 seed 1, which the shape network reads 0.05 (the
# decision 0.99), is left out: its place in the list is the call's, not the ranking's
UNIT = [("fic1", "table4-case2", 1), ("fic2", "table4-case2", 2), ("fic3", "table4-case1", 3),
        ("fic4", "table4-case1", 2), ("fic5", "table4-case2", 3), ("lic1", "table5-case2", 1),
        ("lic2", "table5-case2", 2), ("tic1", "aggressive-tuning", 1),
        ("tic2", "disturbance", 1), ("tic3", "healthy", 1), ("tic4", "aggressive-tuning", 2)]


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    got = capsys.readouterr()
    return code, got.out, got.err


@pytest.fixture(scope="module")
def unit(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("ranked")
    for stem, name, seed in UNIT:
        r = simulate(scenario(name), noise=0.02, seed=seed, duration=3000.0)
        np.savetxt(d / f"{stem}.csv", np.column_stack([r.t, r.op, r.pv]), delimiter=",",
                   header="t,op,pv", comments="", fmt="%.9g")
    return d


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> list[dict[str, Any]]:
    code, out, err = _run(capsys, ["analyze", *argv, "--json", "--op-range", "0", "100",
                                   "--no-site"])  # the ranking's own figures
    assert code == 0, err
    return list(json.loads(out))


def test_the_batch_is_worst_first_with_its_rank_and_sort_file_keeps_the_order(
        unit: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = [str(unit / f"{stem}.csv") for stem, *_ in UNIT]
    got = _json(capsys, *reversed(files))
    assert [g["rank"] for g in got] == list(range(1, len(files) + 1))
    scores = [g["suspicion"] for g in got]
    assert scores == sorted(scores, reverse=True)
    assert {g["loop"] for g in got[:7]} == {"fic1", "fic2", "fic3", "fic4", "fic5", "lic1",
                                              "lic2"}
    kept = _json(capsys, *files, "--sort", "file")
    assert [g["file"] for g in kept] == files  # the order given, each with its rank
    assert sorted(g["rank"] for g in kept) == list(range(1, len(files) + 1))
    top = _json(capsys, *files, "--top", "3")
    assert [g["file"] for g in top] == [g["file"] for g in _json(capsys, *files)[:3]]
    code, out, _err = _run(capsys, ["analyze", *files[:3], "--top", "2"])
    lines = out.splitlines()
    lines = lines[:lines.index("what each verdict means:")]  # the legend follows the table
    assert code == 0 and lines[0].split()[:2] == ["#", "file"] and len(lines) == 3
    assert [line.split()[0] for line in lines[1:]] == ["1", "2"]
    code, _out, err = _run(capsys, ["analyze", *files[:2], "--top", "0"])
    assert code == 2 and "--top 0: give a number of rows, 1 or more" in err


def test_a_manifests_priority_moves_a_loop_up_and_its_loop_names_it(
        unit: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    m = tmp_path / "loops.csv"
    m.write_text(f"file,loop,priority\n{unit / 'fic1.csv'},FIC-1,\n"
                 f"{unit / 'tic1.csv'},TIC-1,10\n{unit / 'fic2.csv'},,0.5\n"
                 f"{unit / 'fic3.csv'},FIC-3,-1\n")
    got = _json(capsys, "--manifest", str(m))
    assert [g.get("loop") for g in got[:3]] == ["FIC-1", "TIC-1", "fic2"]  # 0.99, 10 x
    assert got[1]["suspicion"] == pytest.approx(10 * got[1]["confidence"])  # ~0.07, 0.5 x
    assert "priority" in got[-1]["error"] and "must be > 0" in got[-1]["error"]


def _findings(path: Path, rows: list[tuple[str, str]]) -> Path:
    path.write_text("loop,date,finding\n" + "".join(f"{loop},2024-05-0{k % 9 + 1},{f}\n"
                                                    for k, (loop, f) in enumerate(rows)))
    return path


def test_findings_teach_the_unit_its_calibration(unit: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The crew found the two valves read 0.88 and 0.96 fine: the unit's calibration reads
    them under the threshold and withdraws those calls; the valves found sticking stay
    called; every judged reason says which calibration it used."""
    files = [str(unit / f"{stem}.csv") for stem, *_ in UNIT]
    before = {g["loop"]: g for g in _json(capsys, *files)}
    assert before["lic1"]["verdict"] == before["lic2"]["verdict"] == "stiction"
    crew = _findings(tmp_path / "found.csv", [
        *((f"fic{k}", "stiction") for k in range(1, 6)), ("lic1", "ok"), ("lic2", "ok"),
        *((f"tic{k}", "ok") for k in range(1, 5)), ("nowhere", "stiction"), ("tic1", "rusty")])
    code, out, err = _run(capsys, ["analyze", *files, "--json", "--op-range", "0", "100",
                                   "--findings", str(crew), "--no-site"])
    assert code == 0, err
    after = {g["loop"]: g for g in json.loads(out)}
    assert "found.csv:14: finding 'rusty' is not one of stiction, deadband, ok, other" in err
    assert "calibration of the confidence: site (fitted on 5 sticky and 6 not sticky" in err
    assert "11 of 12 finding(s) matched an analysed file" in err
    for loop in ("lic1", "lic2"):
        assert after[loop]["verdict"] in ("undetermined", "no_stiction")
        assert after[loop]["size"] is None
        assert after[loop]["reason"].startswith(("undetermined at this site", "not stiction "
                                                 "at this site"))
    for k in range(1, 6):
        assert after[f"fic{k}"]["verdict"] == "stiction"
    judged = [g for g in after.values() if g["verdict"] in ("stiction", "undetermined",
                                                            "no_stiction")]
    assert judged and all("Calibration: this site's, from 11 findings" in g["reason"]
                          for g in judged)
    few = _findings(tmp_path / "few.csv", [("fic1", "stiction"), ("tic1", "ok")])
    code, out, err = _run(capsys, ["analyze", *files[:3], "--json", "--findings", str(few),
                                   "--no-site"])
    assert code == 0 and "calibration of the confidence: shipped (too few findings" in err
    assert all("Calibration: shipped (too few findings: 1 sticky, 0 not sticky"
               in g["reason"] for g in json.loads(out) if g["verdict"] == "stiction")


def _need_plant() -> None:
    if not records.PLANT.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"the shared plant records are missing under CI: {records.PLANT}")
        pytest.skip(f"the shared plant records are not there: {records.PLANT}")


def test_the_report_on_the_plant_records_lists_them_in_json_order(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 39's acceptance: `stiction analyze --manifest ... --report` on the shared plant
    records writes a page whose list is --json's order."""
    _need_plant()
    with (records.PLANT / "labels.csv").open(newline="") as fh:
        labels = list(csv.DictReader(fh))
    manifest = tmp_path / "plant.csv"
    manifest.write_text("file,loop\n" + "".join(f"{records.PLANT / r['loop']}.csv,{r['tag']}\n"
                                                for r in labels))
    page = tmp_path / "report.html"
    code, out, err = _run(capsys, ["analyze", "--manifest", str(manifest), "--ts", "10",
                                   "--json", "--report", str(page)])
    assert code == 0, err
    got = json.loads(out)
    assert len(got) == len(labels) == 80
    text = page.read_text(encoding="utf-8")
    listed = re.findall(r"<tr><td class='num'>(\d+)</td><td>(?:<a [^>]*>)?([^<]*)(?:</a>)?"
                        r"<br><small>([^<]*)</small>", text)
    assert len(listed) >= 20
    in_json = [(str(g["rank"]), g["loop"], g["file"]) for g in got
               if g.get("verdict") in ("stiction", "valve_not_responding", "undetermined",
                                       "no_stiction", "propagated")]
    unescaped = [(r, n.replace("&amp;", "&").replace("&#x27;", "'"), f) for r, n, f in listed]
    assert unescaped == in_json
    assert text.count("<section class='valve'") == sum(
        g.get("verdict") in ("stiction", "valve_not_responding", "undetermined")
        for g in got[:25])
