"""`stiction analyze` of a whole unit (issue 28 item 3): several files or a manifest, one row
per loop; a file that cannot be read listed with its error and the others analysed; the
JSON array and the CSV the single-file outputs, file by file."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from detector_fixtures import write_loop_csv

from stiction import Verdict
from stiction.cli import main
from stiction.cli.batch import Progress, flatten, short_reason
from stiction.scenarios import scenario, simulate


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    got = capsys.readouterr()
    return code, got.out, got.err


@pytest.fixture(scope="module")
def unit(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A unit's folder: a sticky loop, a healthy one, a short window (bad_data), a file
    with no numbers in OP, an empty file; no 'missing.csv'."""
    d = tmp_path_factory.mktemp("unit")
    write_loop_csv(d)  # loop.csv
    res = simulate(scenario("healthy"), noise=0.05, seed=1, duration=1500.0)
    np.savetxt(d / "healthy.csv", np.column_stack([res.t, res.op, res.pv]), delimiter=",",
               header="t,op,pv", comments="", fmt="%.9g")
    (d / "short.csv").write_text("t,op,pv\n" + "".join(f"{i},50,{i % 3}\n" for i in range(10)))
    (d / "text.csv").write_text("t,op,pv\n0,abc,2\n1,def,3\n")
    (d / "empty.csv").write_text("")
    return d


def _unlisted(obj: dict[str, Any]) -> dict[str, Any]:
    """A batch's object without what the list worst first adds (issue 39: loop, rank,
    suspicion), as the single file's ``--json`` has it."""
    return {k: v for k, v in obj.items() if k not in ("loop", "rank", "suspicion")}


GOOD = ("loop.csv", "healthy.csv", "short.csv")
BAD = ("text.csv", "empty.csv", "missing.csv")


def _single(capsys: pytest.CaptureFixture[str], path: Path, *extra: str) -> tuple[int, Any]:
    code, out, err = _run(capsys, ["analyze", str(path), "--json", *extra])
    return code, (json.loads(out) if code == 0 else err)


def test_good_unreadable_and_bad_data_files_mixed(unit: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("COLUMNS", "300")  # the terminal's width: no reason cut short
    files = [str(unit / n) for n in ("loop.csv", "text.csv", "healthy.csv", "missing.csv",
                                     "short.csv", "empty.csv")]
    code, out, err = _run(capsys, ["analyze", *files, "--kp", "1", "--op-range", "0", "100",
                                   "--sort", "file"])
    assert code == 0
    lines = out.splitlines()
    lines = lines[:lines.index("what each verdict means:")]  # the legend follows the table
    assert lines[0].split() == ["#", "file", "verdict", "conf", "fd", "fs", "unit", "period",
                                "reason"]  # (#: the rank, issue 39)
    rows = {line.split()[1]: line.split(None, 1)[1] for line in lines[1:]}
    assert list(rows) == files  # one row per file, in the order given
    cells = rows[files[0]].split()
    assert cells[1] == "stiction" and float(cells[3]) == pytest.approx(27.0, rel=0.05)
    assert cells[5:8] == ["%", "of", "span"]
    assert rows[files[4]].split()[1] == "bad_data" and "window too short" in rows[files[4]]
    assert rows[files[1]].split()[1] == "error"
    assert "column 'op' holds no numbers" in rows[files[1]]
    assert "no such file" in rows[files[3]] and "empty file" in rows[files[5]]
    assert "3 of 6 files not analysed" in err
    assert "\r" not in err  # stderr is no terminal here: no progress bar


def test_none_analysed_exits_2(unit: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(capsys, ["analyze", *(str(unit / n) for n in BAD)])
    assert code == 2
    assert "none of 3 files analysed" in err
    assert out.count("error") == 3  # still listed, each with its error


def test_json_array_and_csv_agree_with_single_files(
        unit: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Every object of the array is the file's own --json object plus its `file`; every
    CSV row is that object flattened, value for value; a file not analysed is its error."""
    files = [unit / n for n in (*GOOD, *BAD)]
    out_csv = tmp_path / "unit.csv"
    code, out, _ = _run(capsys, ["analyze", *map(str, files), "--kp", "1", "--json",
                                 "--csv", str(out_csv), "--no-site"])  # each as alone
    assert code == 0
    got = json.loads(out)
    assert isinstance(got, list) and len(got) == len(files)
    with out_csv.open(encoding="utf-8-sig", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == len(files)
    for path, obj, row in zip(files, got, table, strict=True):
        assert obj["file"] == row["file"] == str(path)
        code, alone = _single(capsys, path, "--kp", "1")
        if code != 0:
            assert obj == {"file": str(path), "error": obj["error"]}
            assert obj["error"] in alone and row["error"] == obj["error"]
            assert row["verdict"] == ""
            continue
        assert _unlisted(obj) == {"file": str(path), **alone}
        assert row["error"] == ""
        flat = flatten(alone)
        assert set(flat) <= set(row)
        for key, value in flat.items():
            assert _parsed(row[key], value) == value, (path.name, key)
        assert {k for k, v in row.items() if v != ""} <= {*flat, "file", "loop", "rank",
                                                          "suspicion"}
    sticky = table[0]
    assert sticky["verdict"] == "stiction" and float(sticky["size.fd"]) > 0
    assert sticky["evidence.kano.vote"] == "1"


def _parsed(cell: str, like: Any) -> Any:
    if like is None:
        return None if cell == "" else cell
    if isinstance(like, bool):
        return {"true": True, "false": False}[cell]
    if isinstance(like, int):
        return int(cell)
    if isinstance(like, float):
        return float(cell)
    return cell


def test_one_file_prints_what_it_printed(unit: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """One file: the single object and its text (byte for byte for a window whose
    output does not depend on the learned decision); --csv writes its one row."""
    code, out, _ = _run(capsys, ["analyze", str(unit / "short.csv")])
    assert code == 0
    assert out == ("verdict: bad_data\n"
                   "reason:  window too short: 10 samples, need at least 32\n"
                   f"means:   {Verdict.BAD_DATA.advice}\n"
                   "  oscillating: no\n"
                   "  multi_jump: no\n")
    code, out, _ = _run(capsys, ["analyze", str(unit / "short.csv"), "--json"])
    assert json.loads(out)["verdict"] == "bad_data" and out.startswith("{")
    code, out, _ = _run(capsys, ["analyze", str(unit / "text.csv")])
    assert code == 2
    one = tmp_path / "one.csv"
    code, out, _ = _run(capsys, ["analyze", str(unit / "loop.csv"), "--csv", str(one)])
    assert code == 0 and out.endswith(f"wrote {one}\n") and out.startswith("verdict: stiction")
    (row,) = csv.DictReader(io.StringIO(one.read_text(encoding="utf-8-sig")))
    assert row["verdict"] == "stiction" and row["file"] == str(unit / "loop.csv")


def test_a_hundred_files_in_one_command(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """100 short windows (sticky and healthy loops, 5 minutes each) through one manifest:
    every one analysed, the manifest's paths relative to its folder."""
    (tmp_path / "loops").mkdir()
    sticky = simulate(scenario("table4-case2"), noise=0.02, seed=1, duration=300.0)
    good = simulate(scenario("healthy"), noise=0.05, seed=2, duration=300.0)
    names = []
    for i in range(100):
        res = sticky if i % 2 else good
        shift = 0.01 * i  # every file its own numbers
        name = f"loops/L{i:03d}.csv"
        np.savetxt(tmp_path / name, np.column_stack([res.t, res.op + shift, res.pv]),
                   delimiter=",", header="t,op,pv", comments="", fmt="%.6g")
        names.append(name)
    manifest = tmp_path / "unit.csv"
    manifest.write_text("file\n" + "\n".join(names) + "\n")
    code, out, err = _run(capsys, ["analyze", "--manifest", str(manifest), "--json", "--no-site",
                                   "--sort", "file"])
    assert code == 0, err
    got = json.loads(out)
    assert [g["file"] for g in got] == [str(tmp_path / n) for n in names]
    assert all("error" not in g and g["verdict"] for g in got)
    assert sum(g["verdict"] == "stiction" for g in got) >= 40
    assert err == ""


def test_manifest_cells_override_the_options(unit: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """A cell overrides the command line's option for its file, an empty cell falls back to
    it; a bad row is named LIST:LINE with what is wrong, the others analysed."""
    data = np.loadtxt(unit / "loop.csv", delimiter=",", skiprows=1)
    np.savetxt(tmp_path / "renamed.csv", data[:, 1:], delimiter=";", header="OUT;MEAS",
               comments="", fmt="%.9g")
    (tmp_path / "m").mkdir()
    rel = Path(os.path.relpath(unit / "loop.csv", tmp_path / "m"))
    manifest = tmp_path / "m" / "loops.csv"
    manifest.write_text(
        "File;op;PV;ts;op_lo;op_hi;kp\n"
        f"{rel};;;;;;\n"                            # line 2: the command line's options
        "../renamed.csv;OUT;MEAS;1;0;200;1\n"       # line 3: its own columns, ts, range
        f"{rel};;;;0;;\n"                           # line 4: op_lo without op_hi
        f"{rel};;;abc;;;\n"                         # line 5: ts no number
        f"{rel};;;;;;0\n")                          # line 6: kp 0
    code, out, err = _run(capsys, ["analyze", "--manifest", str(manifest), "--json", "--no-site",
                                   "--op-range", "0", "100", "--sort", "file"])
    assert code == 0, err
    got = json.loads(out)
    assert len(got) == 5
    _, alone = _single(capsys, unit / "loop.csv", "--op-range", "0", "100")
    assert _unlisted(got[0]) == {"file": str(manifest.parent / rel), **alone}
    _, own = _single(capsys, tmp_path / "renamed.csv", "--op", "OUT", "--pv", "MEAS", "--ts",
                     "1", "--op-range", "0", "200", "--kp", "1")
    assert _unlisted(got[1]) == {"file": str(manifest.parent / "../renamed.csv"), **own}
    assert own["size"]["fd"] == pytest.approx(alone["size"]["fd"] / 2, rel=0.01)  # 0-200 span
    assert got[2]["error"] == f"{manifest}:4: column 'op_lo' without 'op_hi': give both " \
        "(the OP at 0 % and 100 % valve span) or neither"
    assert got[3]["error"] == f"{manifest}:5: column 'ts': 'abc' is not a number"
    assert got[4]["error"] == f"{manifest}:6: column 'kp': '0' must be not 0"
    assert "3 of 5 files not analysed" in err


@pytest.mark.parametrize(("text", "message"), [
    ("path\na.csv\n", ":1: unknown column 'path' (a manifest has 'file' and any of ts,"),
    ("kp\n1\n", ":1: no column 'file' (columns: kp)"),
    ("file\n", ": no loop listed under the header"),
    ("", ": empty manifest"),
])
def test_an_unusable_manifest_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         text: str, message: str) -> None:
    manifest = tmp_path / "loops.csv"
    manifest.write_text(text)
    code, _, err = _run(capsys, ["analyze", "--manifest", str(manifest)])
    assert code == 2
    assert f"stiction: error: {manifest}{message}" in err


def test_no_file_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _run(capsys, ["analyze", "--kp", "1"])
    assert code == 2 and "give a CSV file, several, or --manifest LIST" in err


def test_plots_one_png_per_file(unit: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    folder = tmp_path / "plots"
    code, out, _ = _run(capsys, ["analyze", str(unit / "short.csv"), str(unit / "text.csv"),
                                 str(unit / "short.csv"), "--plot", str(folder)])
    assert code == 0 and f"wrote {folder}" in out
    assert sorted(p.name for p in folder.iterdir()) == ["short-2.png", "short.png"]


def test_short_reason_and_progress_bar() -> None:
    assert short_reason("not stiction, confidence of stiction 0.05. Tests: stiction: kano; "
                        "cannot tell: horch. Weighed most in the decision: for stiction: the "
                        "shape of OP and PV.") == "Tests: stiction: kano; cannot tell: horch."
    assert short_reason("undetermined, confidence of stiction 0.55: between what the tests "
                        "tell apart. Tests: cannot tell: kano. Nothing weighed much either "
                        "way in the decision.") == "between what the tests tell apart."
    stream = io.StringIO()
    bar = Progress(4, stream)
    bar.show(1, "b.csv")
    bar.clear()
    text = stream.getvalue()
    assert "analysing 2/4 [######..................] b.csv" in text
    assert text.endswith("\r")
