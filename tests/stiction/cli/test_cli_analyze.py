"""`stiction analyze` and `stiction reproduce`: outputs and every unusable-input case."""

from __future__ import annotations

import datetime as dt
import json
import re
from pathlib import Path

import numpy as np
import pytest
from detector_fixtures import write_loop_csv

from stiction import Assessment, Verdict, cli
from stiction.cli import main
from stiction.cli import reproduce as cli_reproduce
from stiction.paper.reproduce import reproduce
from stiction.paper.tables import PAPER_ROWS


@pytest.fixture(scope="module")
def loop_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_loop_csv(tmp_path_factory.mktemp("cli"))


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "in.csv"
    p.write_text(text)
    return p


def _error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    return capsys.readouterr().err


def test_json_is_one_assessment_with_sizes_in_one_unit(
        loop_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 23 item 7: sizes in % of span with --op-range (as the Modbus registers), in
    OP units without it, always under `size` with their unit; never fractions beside OP
    units, the jump wherever fd and fs are, cycles_used only when cycles were read."""
    assert main(["analyze", str(loop_csv), "--kp", "1", "--op-range", "0", "100", "--json"]) == 0
    out = capsys.readouterr().out
    got = json.loads(out)
    assert out.count("\n") == 1 and got["verdict"] == "stiction"
    assert not {"fd", "fs", "jump", "fd_op", "fs_op", "cycles_used"} & set(got)
    size = got["size"]
    assert size["unit"] == "% of span"
    assert size["fd"] == pytest.approx(27.0, rel=0.05)
    assert size["fs"] == pytest.approx(30.0, rel=0.05)
    assert size["jump"] == pytest.approx(1.99 * (size["fs"] - size["fd"]), rel=1e-6)
    assert size["cycles_used"] >= 2
    assert main(["analyze", str(loop_csv), "--json"]) == 0
    size = json.loads(capsys.readouterr().out)["size"]
    assert size["unit"] == "OP units" and size["fd"] == pytest.approx(27.0, rel=0.05)
    assert size["fs"] is None and size["jump"] is None  # fs needs kp


def test_text_output(loop_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(loop_csv)]) == 0
    out = capsys.readouterr().out
    assert "verdict: stiction" in out
    assert re.search(r"^  fd: 2\d\.\d+ OP units$", out, re.M), out
    assert main(["analyze", str(loop_csv), "--op-range", "0", "100", "--kp", "1"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  fd: 2\d\.\d+ % of span$", out, re.M), out
    assert re.search(r"^  jump: \d\.\d+ % of span$", out, re.M), out
    assert re.search(r"^  cycles_used: \d+ \(limit cycles whose jumps were read\)$", out, re.M)


def test_a_size_from_the_fitted_valve_has_its_jump_and_no_cycle_count() -> None:
    """Issue 23 item 7: a valve sized by the fit to PV (no cycles read) showed
    `cycles_used: 0` beside its fd and `jump: null` beside fd and fs."""
    a = Assessment(Verdict.STICTION, "test", fd=0.20, fs=0.25, fd_op=20.0, fs_op=25.0)
    view = cli.analyze.view(a)
    assert view["size"] == {"unit": "% of span", "fd": 20.0, "fs": 25.0,
                            "jump": pytest.approx(1.99 * 5.0)}
    b = Assessment(Verdict.STICTION, "test", fd_op=2.0, fs_op=2.5)  # no op_range
    assert cli.analyze.view(b)["size"] == {"unit": "OP units", "fd": 2.0, "fs": 2.5,
                                           "jump": pytest.approx(1.99 * 0.5)}
    assert cli.analyze.view(Assessment(Verdict.NO_STICTION, "test"))["size"] is None


def test_utf8_byte_order_mark_is_read(tmp_path: Path, loop_csv: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + loop_csv.read_bytes())
    assert main(["analyze", str(p)]) == 0
    assert "verdict: stiction" in capsys.readouterr().out


def test_historian_time_stamps_go_on_a_grid(tmp_path: Path, loop_csv: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A repeated time stamp keeps its last row; rows missing from the grid are gaps."""
    data = np.genfromtxt(loop_csv, delimiter=",", names=True)
    keep = np.ones(data.size, dtype=bool)
    keep[[50, 51, 700]] = False  # three rows missing
    rows = [(t, o, v) for (t, o, v), k in zip(data, keep, strict=True) if k]
    rows.insert(10, (rows[10][0], 0.0, 0.0))  # repeated stamp: the later row wins
    p = tmp_path / "hist.csv"
    p.write_text("t,op,pv\n" + "".join(f"{t:g},{o:.9g},{v:.9g}\n" for t, o, v in rows))
    assert main(["analyze", str(p)]) == 0
    out = capsys.readouterr().out
    assert "verdict: stiction" in out
    assert "1 rows repeat a time stamp (on a 1 s grid): the last of each kept" in out
    assert "3 samples missing from the 1 s time grid: treated as gaps" in out
    assert "interpolated 3 missing samples" in out


def test_columns_and_ts_options(tmp_path: Path, loop_csv: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    data = np.loadtxt(loop_csv, delimiter=",", skiprows=1)
    p = tmp_path / "renamed.csv"
    np.savetxt(p, data[:, 1:], delimiter=",", header="OUT,MEAS", comments="", fmt="%.9g")
    assert main(["analyze", str(p), "--op", "OUT", "--pv", "MEAS", "--ts", "1", "--json",
                 "--op-range", "0", "100", "--delay", "0", "--process", "self-regulating"]) == 0
    assert json.loads(capsys.readouterr().out)["verdict"] == "stiction"


def test_plot(loop_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    png = tmp_path / "a.png"
    assert main(["analyze", str(loop_csv), "--kp", "1", "--plot", str(png)]) == 0
    assert png.stat().st_size > 1000
    assert f"wrote {png}" in capsys.readouterr().out


def test_unfit_data_is_bad_data_not_an_error(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "t,op,pv\n" + "".join(f"{i},50,{i % 3}\n" for i in range(10)))
    assert main(["analyze", str(p), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["verdict"] == "bad_data"
    assert "too short" in d["reason"]


def test_missing_cells_are_gaps(tmp_path: Path, loop_csv: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    lines = loop_csv.read_text().splitlines()
    lines[100] = lines[100].rsplit(",", 1)[0] + ","
    lines[200] = lines[200].rsplit(",", 1)[0] + ",nan"
    p = _write(tmp_path, "\n".join(lines) + "\n")
    assert main(["analyze", str(p), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["verdict"] == "stiction"
    assert any("interpolated 2" in w for w in d["warnings"])


# ------------------------------------------------------------------- unusable input
def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _error(capsys, ["analyze", str(tmp_path / "nope.csv")])
    assert "nope.csv: no such file" in err


def test_empty_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "empty file" in _error(capsys, ["analyze", str(_write(tmp_path, ""))])


@pytest.mark.parametrize("col", ["op", "pv"])
def test_missing_column(tmp_path: Path, capsys: pytest.CaptureFixture[str], col: str) -> None:
    header = "t,op" if col == "pv" else "t,pv"
    p = _write(tmp_path, f"{header}\n0,1\n1,2\n")
    assert f"no column '{col}'" in _error(capsys, ["analyze", str(p)])


def test_missing_time_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "op,pv\n1,2\n2,3\n")
    err = _error(capsys, ["analyze", str(p)])
    assert "no time column 't' (columns: op, pv); give --time COL or --ts S" in err


def test_a_column_without_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Text cells are gaps (a historian's 'I/O Timeout'), but a column of text only is the
    wrong column."""
    p = _write(tmp_path, "t,op,pv\n0,abc,2\n1,def,3\n")
    err = _error(capsys, ["analyze", str(p)])
    assert "column 'op' holds no numbers (e.g. 'abc'); is it the right column?" in err


@pytest.mark.parametrize("rows", ["", "0,1,2\n"])
def test_fewer_than_two_samples(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                rows: str) -> None:
    p = _write(tmp_path, "t,op,pv\n" + rows)
    assert "need at least 2" in _error(capsys, ["analyze", str(p)])


def test_time_going_backwards(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "t,op,pv\n" + "".join(f"{t},1,2\n" for t in (0, 2, 1)))
    err = _error(capsys, ["analyze", str(p)])
    assert "time goes backwards in column 't': '2' (line 3) -> '1' (line 4): sort the rows" \
        in err


def test_one_time_stamp_only(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "t,op,pv\n" + "".join(f"{t},1,2\n" for t in (5, 5, 5)))
    assert "holds one time only ('5'); give --ts S" in _error(capsys, ["analyze", str(p)])


def test_missing_time(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "t,op,pv\n0,1,2\n,1,2\n")
    assert "line 3, column 't': no time; every row needs one" in _error(capsys,
                                                                          ["analyze", str(p)])


@pytest.mark.parametrize(
    ("args", "option"),
    [(["--ts", "0"], "--ts"), (["--kp", "0"], "--kp"), (["--delay", "-1"], "--delay"),
     (["--op-range", "100", "0"], "--op-range")],
)
def test_bad_option_values_name_the_option(loop_csv: Path, capsys: pytest.CaptureFixture[str],
                                           args: list[str], option: str) -> None:
    argv = ["analyze", str(loop_csv), *args]
    if args[0] == "--ts":
        argv = ["analyze", str(loop_csv), "--ts", "0"]
        p = loop_csv.with_name("no_t.csv")
        data = np.loadtxt(loop_csv, delimiter=",", skiprows=1)
        np.savetxt(p, data[:, 1:], delimiter=",", header="op,pv", comments="")
        argv = ["analyze", str(p), "--ts", "0"]
    assert f"error: {option}:" in _error(capsys, argv)


def test_time_and_ts_are_exclusive(loop_csv: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "not allowed with" in _error(capsys, ["analyze", str(loop_csv), "--time", "t",
                                                 "--ts", "1"])


def test_reproduce_rejects_negative_noise(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--noise" in _error(capsys, ["reproduce", "--noise", "-1"])


def test_reproduce_prints_paper_beside_ours(monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    def table4_only(**kw: object) -> object:
        return reproduce(rows=[r for r in PAPER_ROWS if r.table == 4], **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(cli_reproduce, "reproduce", table4_only)
    assert main(["reproduce", "--noise", "0"]) == 0
    out = capsys.readouterr().out
    assert "PV noise SD 0," in out
    assert out.count("stiction") >= 2
    assert "0.270 (  0.0%)" in out  # the paper's Table 4 case 2 fd
    assert "mean abs error paper" in out


# ------------------------------------------------------------ historian exports (issue 23)

def _export(loop_csv: Path, path: Path, *, sep: str, stamp: str, comma: bool,
            header: str = "Timestamp{s}FIC101.OP{s}FIC101.PV", texts: dict[int, str] | None = None,
            encoding: str = "utf-8") -> Path:
    """The sticky loop as a historian exports it: ``stamp`` a strftime form of the time
    (from 2024-03-01 06:00:00, 1 s rows), ``texts`` PV cells replaced by text."""
    data = np.loadtxt(loop_csv, delimiter=",", skiprows=1)
    t0 = dt.datetime(2024, 3, 1, 6, 0, 0)
    lines = [header.format(s=sep)]
    for i, (t, op, pv) in enumerate(data):
        cells = [f"{op:.4f}", f"{pv:.4f}"]
        if comma:
            cells = [c.replace(".", ",") for c in cells]
        if texts and i in texts:
            cells[1] = texts[i]
        lines.append(sep.join([(t0 + dt.timedelta(seconds=float(t))).strftime(stamp), *cells]))
    path.write_text("\r\n".join(lines) + "\r\n", encoding=encoding)
    return path


@pytest.mark.parametrize("form", [
    (";", "%Y-%m-%d %H:%M:%S", True, "utf-8"),       # ISO, ';' and decimal commas
    (";", "%Y-%m-%dT%H:%M:%SZ", False, "utf-8-sig"),  # ISO with Z, decimal points
    ("\t", "%d.%m.%Y %H:%M:%S", True, "utf-16"),     # Excel "Unicode text", German dates
    (",", "%m/%d/%Y %I:%M:%S %p", False, "utf-8"),   # US dates, 12-hour clock
])
def test_historian_exports_are_read_as_they_are(
        tmp_path: Path, loop_csv: Path, capsys: pytest.CaptureFixture[str],
        form: tuple[str, str, bool, str]) -> None:
    """Issue 23 item 3: the delimiter sniffed, decimal commas, date-time stamps (the time
    column found by its name), column names in any case, and text cells in PV as gaps,
    counted in a warning; the verdict is the one of the plain file."""
    sep, stamp, comma, encoding = form
    texts = {200: "I/O Timeout", 201: "I/O Timeout", 900: "Shutdown"}
    p = _export(loop_csv, tmp_path / "export.csv", sep=sep, stamp=stamp, comma=comma,
                texts=texts, encoding=encoding)
    assert main(["analyze", str(p), "--op", "fic101.op", "--pv", "FIC101.pv", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["verdict"] == "stiction", got["reason"]
    assert "column 'FIC101.PV': 3 text cells treated as gaps: 'I/O Timeout' 2, " \
        "'Shutdown' 1" in got["warnings"]
    assert got["size"]["fd"] == pytest.approx(27.0, rel=0.05)


def test_a_time_that_is_no_time_says_which_forms_are(tmp_path: Path, loop_csv: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "Time;OP;PV\n2024-03-01 06:00:00;1;2\nyesterday;1;2\n")
    err = _error(capsys, ["analyze", str(p)])
    assert "line 3, column 'Time': not a time: 'yesterday'; times may be seconds, or dates " \
        "like 2024-03-01 06:00:00" in err
    assert "or give --ts S" in err
    p = _write(tmp_path, "Timestamp;FIC101.OP\n0;1\n1;2\n")
    err = _error(capsys, ["analyze", str(p), "--op", "FIC101.OP"])
    assert "no column 'pv' (columns: Timestamp, FIC101.OP); give --pv COL" in err


def test_compressed_historian_values_are_refused(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Recorded (compressed) values come at irregular times: not samples of one grid."""
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(1.0, 30.0, 400))
    p = _write(tmp_path, "t,op,pv\n" + "".join(f"{x:.1f},1,2\n" for x in t))
    err = _error(capsys, ["analyze", str(p)])
    assert "time stamps irregular" in err
    assert "export interpolated values at a fixed interval, or give --ts S" in err
