"""Historian exports with their quirks (issue 32 items 1 and 2): each one read to the same
verdict and sizes as the clean export of the same numbers, or refused (exit 2) with a
message naming the quirk; never a different answer without a word.

The clean export is a simulated sticky loop (deterministic), written plainly; each quirky
export writes the same numbers (so the analysis sees the same floats) as a historian would.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import zoneinfo
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest

from stiction.cli import decimals, main
from stiction.scenarios import simulate


@pytest.fixture(scope="module")
def loop() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    res = simulate("table4-case2", noise=0.02, seed=4)
    return res.t, res.op, res.pv


def _write(path: Path, header: Sequence[str], rows: Sequence[Sequence[str]], sep: str,
           quote: bool = False) -> Path:
    def cell(c: str) -> str:
        return f'"{c}"' if quote and sep in c else c
    lines = [sep.join(header)] + [sep.join(cell(c) for c in r) for r in rows]
    path.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8")
    return path


def _run(capsys: pytest.CaptureFixture[str], path: Path, *args: str) -> dict:
    assert main(["analyze", str(path), "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


def _error(capsys: pytest.CaptureFixture[str], path: Path, *args: str) -> str:
    with pytest.raises(SystemExit) as info:
        main(["analyze", str(path), *args])
    assert info.value.code == 2
    return capsys.readouterr().err


def _same(got: dict, clean: dict) -> None:
    """The same answer: verdict, confidence, sizes and every figure but the warnings (of a
    sticky valve found and sized: the comparison is of a real answer)."""
    assert clean["verdict"] == "stiction" and clean["size"]["fd"] > 0, clean["reason"]
    assert {k: v for k, v in got.items() if k != "warnings"} == \
        {k: v for k, v in clean.items() if k != "warnings"}


def _clean(tmp_path: Path, capsys: pytest.CaptureFixture[str], t: np.ndarray,
           op: np.ndarray, pv: np.ndarray, *, fmt: str = ".4f") -> dict:
    rows = [(f"{a:g}", f"{b:.4f}", format(c, fmt)) for a, b, c in zip(t, op, pv, strict=True)]
    return _run(capsys, _write(tmp_path / "clean.csv", ("t", "op", "pv"), rows, ","))


def _comma_style(cell: str) -> str:
    """``1,118.5`` -> ``1.118,5``."""
    return cell.translate(str.maketrans(",.", ".,"))


# ----------------------------------------------------------------- thousands separators
@pytest.mark.parametrize("offset", [1100.0, 948.0], ids=["above-1000", "across-1000"])
@pytest.mark.parametrize("style", ["tab-point", "semicolon-comma", "tab-comma"])
def test_thousands_separators_read_as_the_clean_export(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        offset: float, style: str) -> None:
    """Issue 32 item 1: a tab export with PV above 1,000 written `1,118.5` lost every cell
    (or, across 1,000, the cells above it as 'text cells treated as gaps'); read now, the
    answer is the clean export's and a warning says how the numbers were read."""
    t, op, pv = loop
    pv = pv + offset
    assert offset > 1000 or (pv.min() < 1000 < pv.max())
    clean = _clean(tmp_path, capsys, t, op, pv)
    sep, fix = {"tab-point": ("\t", str), "semicolon-comma": (";", _comma_style),
                "tab-comma": ("\t", _comma_style)}[style]
    rows = [(f"{a:g}", fix(f"{b:,.4f}"), fix(f"{c:,.4f}")) for a, b, c in zip(t, op, pv,
                                                                            strict=True)]
    got = _run(capsys, _write(tmp_path / "export.csv", ("t", "op", "pv"), rows, sep))
    _same(got, clean)
    mark = "." if style == "tab-point" else ","
    assert any(w.startswith("column 'pv': thousands grouped") and f"{mark!r} is the decimal "
               "mark" in w for w in got["warnings"]), got["warnings"]
    assert not any("text cells" in w for w in got["warnings"])


def test_integers_grouped_read_from_the_other_columns(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    """Issue 32 item 1, the silent misread: every PV cell like `5,118` in a tab export was
    read as 5.118 (with --kp: stiction, fs a thousand times too large, no word). PV alone
    cannot tell; OP's `50.1234` shows '.' is this export's decimal mark, so PV is 5118,
    and a warning says so."""
    t, op, pv = loop
    pv = np.round(100.0 * pv)
    clean = _clean(tmp_path, capsys, t, op, pv, fmt=".0f")
    rows = [(f"{a:g}", f"{b:.4f}", f"{c:,.0f}") for a, b, c in zip(t, op, pv, strict=True)]
    got = _run(capsys, _write(tmp_path / "export.csv", ("t", "op", "pv"), rows, "\t"),
               "--kp", "100")
    clean_kp = _run(capsys, tmp_path / "clean.csv", "--kp", "100")
    _same(got, clean_kp)
    assert clean["verdict"] == clean_kp["verdict"]
    assert f"column 'pv': {rows[0][2]!r} read as {pv[0]:.0f}: '.' is the decimal mark of " \
        "this export (column 'op': " in " ".join(got["warnings"])


def test_a_column_that_reads_two_ways_is_refused_naming_both(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    """Issue 32 item 1: every number of the file like `1,118` or `50.125` (OP with three
    decimals): no cell tells which mark is the decimal one. Issue 38 item 5: OP's range does
    (50.125 lies inside 0-100, 50125 far outside): read as the clean export with --decimal .,
    said so; where the range given holds both readings, exit 2 with both."""
    t, op, pv = loop
    op = np.round(op, 3)
    pv = np.round(100.0 * pv)
    assert op.min() >= 1.0 and pv.min() >= 1000
    rows = [(f"2024-03-01 06:{int(a) // 60:02d}:{int(a) % 60:02d}", f"{b:.3f}", f"{c:,.0f}")
            for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path / "export.txt", ("Time", "op", "pv"), rows[:3000], "\t")
    clean = [(f"{a:g}", f"{b:.3f}", f"{c:.0f}") for a, b, c in zip(t, op, pv, strict=True)]
    want = _run(capsys, _write(tmp_path / "clean.csv", ("t", "op", "pv"), clean, ","))
    assert not any(w.startswith("column") for w in want["warnings"])  # a CSV: '.' decimal
    got = _run(capsys, path)
    _same(got, want)
    _same(_run(capsys, path, "--decimal", "."), want)
    said = " ".join(got["warnings"])
    assert f"column 'op': {rows[0][1]!r} read as {op[0]:.10g}: read with '.' grouping " \
        f"thousands it would be {op[0] * 1000:.10g}, outside the OP range 0-100" in said
    assert f"column 'pv': {rows[0][2]!r} read as {pv[0]:.10g}: '.' is the decimal mark of " \
        "this export (column 'op' reads inside its OP range 0-100 only so)" in said
    err = _error(capsys, path, "--op-range", "0", "100000")
    assert f"column 'op': {rows[0][1]!r} (line 2) reads as {op[0]:.10g} with '.' the decimal " \
        f"mark or as {op[0] * 1000:.10g} with '.' grouping thousands, and no number in the " \
        "file tells which; give --decimal . " in err


def test_the_pv_column_alone_names_its_two_readings(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    rows = [(str(i), "50", f"{1 + i % 7},{118 + i % 3}") for i in range(20)]
    err = _error(capsys, _write(tmp_path / "e.csv", ("t", "op", "pv"), rows, "\t"))
    assert "column 'pv': '1,118' (line 2) reads as 1118 with ',' grouping thousands or as " \
        "1.118 with ',' the decimal mark, and no number in the file tells which; give " \
        "--decimal . (reads 1118) or --decimal , (reads 1.118)" in err


@pytest.mark.parametrize("fmt", [",.4f", ",.0f"], ids=["12,504.3", "12,504"])
def test_quoted_grouped_numbers_in_a_comma_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...], fmt: str) -> None:
    """Issue 32 item 1: `"12,504.3"` in a comma file was 'holds no numbers'. `"12,504"`
    alone reads either way: in a ','-separated file '.' is the decimal mark, said so."""
    t, op, pv = loop
    pv = np.round(12000.0 + 10.0 * pv, 4 if "4" in fmt else 0)
    clean = _clean(tmp_path, capsys, t, op, pv)
    rows = [(f"{a:g}", f"{b:.4f}", format(c, fmt)) for a, b, c in zip(t, op, pv, strict=True)]
    got = _run(capsys, _write(tmp_path / "export.csv", ("t", "op", "pv"), rows, ",",
                              quote=True))
    _same(got, clean)
    assert any(w.startswith("column 'pv': ") for w in got["warnings"])
    assert not any(w.startswith("column 'op'") or w.startswith("column 't'")
                   for w in got["warnings"]), got["warnings"]


def test_a_column_with_both_decimal_marks_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = [(str(i), "50", "12.5" if i != 7 else "12,5") for i in range(20)]
    err = _error(capsys, _write(tmp_path / "e.csv", ("t", "op", "pv"), rows, "\t"))
    assert "column 'pv' mixes decimal marks: '12.5' (line 2) has a decimal point, '12,5' " \
        "(line 9) a decimal comma; give --decimal . or --decimal ," in err


@pytest.mark.parametrize(("cell", "point", "comma"), [
    ("1,118", 1118.0, 1.118), ("1.118", 1.118, 1118.0), ("45.3", 45.3, None),
    ("45,3", None, 45.3), ("0,118", None, 0.118), ("0.118", 0.118, None),
    ("1,118.5", 1118.5, None), ("1.118,5", None, 1118.5), ("-12,504.3", -12504.3, None),
    ("1 118,5", None, 1118.5), ("1'118.5", 1118.5, None), ("1\u00a0118,5", None, 1118.5),
    ("1,118,500", 1118500.0, None), ("1.118.500", None, 1118500.0), ("12", 12.0, 12.0),
    ("1e5", 1e5, 1e5), ("1,5e3", None, 1500.0), ("I/O Timeout", None, None),
    ("11,18", None, 11.18), ("1_000", None, None), ("1.5,3", None, None),
])
def test_each_cell_read_both_ways(cell: str, point: float | None,
                                  comma: float | None) -> None:
    assert decimals.value(cell, ".") == point
    assert decimals.value(cell, ",") == comma
    both = point is not None and comma is not None and point != comma
    assert decimals.kind(cell) == ("both" if both else "." if comma is None and point
                                   is not None else "," if point is None and comma is not None
                                   else None)


# ------------------------------------------------------------------- historian quirks (item 2)
UTC0 = dt.datetime(2024, 3, 1, 6, 0, 0, tzinfo=dt.UTC)


def _export(path: Path, loop: tuple[np.ndarray, ...], stamp: Callable[[dt.datetime], str], *,
            header: Sequence[str] = ("Time", "FIC101.OP", "FIC101.PV"), start: dt.datetime = UTC0,
            sep: str = "\t") -> tuple[Path, list[list[str]]]:
    """The loop as a historian writes it: ``stamp`` writes each UTC time stamp."""
    t, op, pv = loop
    rows = [[stamp(start + dt.timedelta(seconds=float(a))), f"{b:.4f}", f"{c:.4f}"]
            for a, b, c in zip(t, op, pv, strict=True)]
    return _write(path, header, rows, sep), rows


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory, loop: tuple[np.ndarray, ...]) -> dict:
    """The clean export's answer (t in seconds, ',' separated, the same numbers)."""
    t, op, pv = loop
    rows = [(f"{a:g}", f"{b:.4f}", f"{c:.4f}") for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path_factory.mktemp("clean") / "clean.csv", ("t", "op", "pv"), rows, ",")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["analyze", str(path), "--json"]) == 0
    return json.loads(out.getvalue())


def _quirk(capsys: pytest.CaptureFixture[str], path: Path, *args: str) -> dict:
    return _run(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV", *args)


def _iso(u: dt.datetime) -> str:
    return u.strftime("%Y-%m-%d %H:%M:%S")


def _local(zone: str, form: str = "%Y-%m-%d %H:%M:%S %Z") -> Callable[[dt.datetime], str]:
    return lambda u: u.astimezone(zoneinfo.ZoneInfo(zone)).strftime(form)


HEADER = ("Time", "FIC101.OP", "FIC101.PV")


@pytest.mark.parametrize("head", [[["", "%", "m3/h"]],
                                  [["Description", "FIC101 output", "FIC101 flow"],
                                   ["Units", "%", "m3/h"]]], ids=["units", "description-units"])
def test_rows_of_units_under_the_header_are_skipped_and_said(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict, head: list[list[str]]) -> None:
    """Issue 32 item 2: a units row under the header ended in 'line 2: no time; every row
    needs one, or give --ts', and --ts threw the time stamps away."""
    _, rows = _export(tmp_path / "x.txt", loop, _iso)
    path = _write(tmp_path / "export.txt", HEADER, [*head, *rows], "\t")
    got = _quirk(capsys, path)
    _same(got, clean)
    shown = ", ".join(f"{h} {c!r}" for h, c in zip(HEADER, head[0], strict=True) if c)
    assert "line 2 under the header holds no number and no time (units or a description?): " \
        f"skipped ({shown})" in got["warnings"]
    assert len([w for w in got["warnings"] if "under the header" in w]) == len(head)


@pytest.mark.parametrize("order", [(0, 1, 2), (0, 2, 1)], ids=["same-order", "other-order"])
def test_a_header_repeated_where_two_exports_were_appended(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict, order: tuple[int, ...]) -> None:
    """Issue 32 item 2: 'line 1502: not a time: 'Time''. The second export's header (and
    its units row) skipped, its columns put back in the first header's order."""
    _, rows = _export(tmp_path / "x.txt", loop, _iso)
    second = [[r[j] for j in order] for r in rows[600:]]
    path = _write(tmp_path / "export.txt", HEADER,
                  [["", "%", "m3/h"], *rows[:600], [HEADER[j] for j in order],
                   [["", "%", "m3/h"][j] for j in order], *second], "\t")
    got = _quirk(capsys, path)
    _same(got, clean)
    said = "skipped" if order == (0, 1, 2) else "the rows after it put back in the first " \
        "header's column order"
    assert f"the header repeats at line 603 (two exports appended?): {said}" in got["warnings"]


def test_appended_exports_that_overlap_are_refused_naming_the_join(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    _, rows = _export(tmp_path / "x.txt", loop, _iso)
    path = _write(tmp_path / "export.txt", HEADER, [*rows[:600], HEADER, *rows[550:]], "\t")
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "time goes backwards in column 'Time': '2024-03-01 06:09:59' (line 601) -> " \
        "'2024-03-01 06:09:10' (line 603), where the header repeats at line 602: two exports " \
        "appended that overlap in time" in err


def test_a_header_of_other_columns_inside_the_file_is_named(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    _, rows = _export(tmp_path / "x.txt", loop, _iso)
    path = _write(tmp_path / "export.txt", HEADER,
                  [*rows[:600], ["Time", "FIC102.OP", "FIC102.PV"], *rows[600:]], "\t")
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "line 602, column 'Time': not a time: 'Time'; it names a column: a header of " \
        "other columns where two exports were appended?" in err


def test_zone_abbreviations_across_a_daylight_saving_change(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """Issue 32 item 2: `2026-03-01 06:00:00 CET` was refused. Local stamps with their
    abbreviation across the spring change (01:59:59 CET -> 03:00:00 CEST) read as one clock."""
    start = dt.datetime(2024, 3, 31, 0, 50, tzinfo=dt.UTC)
    path, rows = _export(tmp_path / "export.txt", loop, _local("Europe/Berlin"), start=start)
    assert rows[0][0] == "2024-03-31 01:50:00 CET" and rows[-1][0].endswith("CEST")
    got = _quirk(capsys, path)
    _same(got, clean)
    assert "time zones read: CEST +02:00, CET +01:00" in got["warnings"]


def test_an_abbreviation_of_several_zones_needs_tz(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """CDT and CST are US Central's and Cuba's (CST China's too): refused without --tz,
    read with it, across the autumn change whose hour 01:00-02:00 comes twice."""
    start = dt.datetime(2024, 11, 3, 6, 50, tzinfo=dt.UTC)
    path, rows = _export(tmp_path / "export.txt", loop, _local("America/Chicago"), start=start)
    assert rows[0][0] == "2024-11-03 01:50:00 CDT" and rows[-1][0] == "2024-11-03 01:09:59 CST"
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "line 2, column 'Time': '2024-11-03 01:50:00 CDT': zone 'CDT' names several zones " \
        "(US Central -05:00 or Cuba -04:00): give --tz with the historian's zone" in err
    _same(_quirk(capsys, path, "--tz", "America/Chicago"), clean)


def test_local_stamps_without_a_zone_at_the_autumn_change(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """Stamps in local time without a zone go back an hour at the end of summer time: the
    message says so and how to read them; --tz reads them, the repeated hour in row order."""
    start = dt.datetime(2024, 10, 27, 0, 50, tzinfo=dt.UTC)
    path, _ = _export(tmp_path / "export.txt", loop, _local("Europe/Berlin", "%d.%m.%Y %H:%M:%S"),
                      start=start)
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "time goes backwards in column 'Time': '27.10.2024 02:59:59' (line 601) -> " \
        "'27.10.2024 02:00:00' (line 602): an hour back, the end of summer time in local time " \
        "stamps? Give --tz with the historian's zone" in err
    _same(_quirk(capsys, path, "--tz", "Europe/Berlin"), clean)


def test_time_messages_show_stamps_as_written(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 32 item 2: 'time goes backwards: 1.70927e+09 -> 1.70927e+09 s'."""
    rows = [(t, "1", "2") for t in ("1709270000", "1709270002", "1709270001")]
    err = _error(capsys, _write(tmp_path / "e.csv", ("t", "op", "pv"), rows, ","))
    assert "time goes backwards in column 't': '1709270002' (line 3) -> '1709270001' (line 4)" \
        in err


@pytest.mark.parametrize(("tz", "said"), [
    ("Mars/Olympus", "argument --tz: unknown zone 'Mars/Olympus': give an IANA zone such as "
     "Europe/Berlin"),
    (None, "zone 'XYZT' is not one this reader knows: give --tz with the historian's zone")])
def test_unknown_zones_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                 tz: str | None, said: str) -> None:
    rows = [(f"2024-03-01 06:00:0{i} XYZT", "1", "2") for i in range(3)]
    path = _write(tmp_path / "e.csv", ("t", "op", "pv"), rows, ",")
    assert said in _error(capsys, path, *(["--tz", tz] if tz else []))


# ------------------------------------------------------------------------ plots (item 9)
@pytest.mark.parametrize("zone", ["Europe/Berlin", None], ids=["CET", "seconds"])
def test_the_plot_is_on_the_exports_own_time_axis(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        monkeypatch: pytest.MonkeyPatch, zone: str | None) -> None:
    """Issue 32 item 9: the plot counted time from 0 s even when the export had date-times,
    so the stretch could not be found on the historian's trend; the test-vote marks (+ - .)
    were not explained. Leading gaps trimmed by the analysis move the start with them."""
    figure = pytest.importorskip("matplotlib.figure")
    figures: list = []
    monkeypatch.setattr(figure.Figure, "savefig",
                        lambda self, *a, **k: figures.append(self))
    if zone is None:
        t, op, pv = loop
        rows = [[f"{a + 5000:g}", f"{b:.4f}", f"{c:.4f}"] for a, b, c in
                zip(t, op, pv, strict=True)]
        path = _write(tmp_path / "export.csv", HEADER, rows, ",")
    else:
        path, rows = _export(tmp_path / "export.txt", loop, _local(zone))
    for r in rows[:3]:
        r[2] = "I/O Timeout"  # three leading gaps: the window starts at the fourth row
    path = _write(path, HEADER, rows, "\t" if zone else ",")
    assert main(["analyze", str(path), "--op", "FIC101.OP", "--pv", "FIC101.PV", "--plot",
                 str(tmp_path / "a.png")]) == 0
    ax_op, ax_pv, ax_pattern = figures[0].axes
    first = ax_op.lines[0].get_xdata()[0]
    if zone is None:
        assert first == 5003.0
        assert ax_pv.get_xlabel() == "t, s (the export's time)"
    else:
        assert first == dt.datetime(2024, 3, 1, 7, 0, 3, tzinfo=zoneinfo.ZoneInfo(zone))
        assert first.strftime("%Y-%m-%d %H:%M:%S %Z") == rows[3][0]
        assert ax_pv.get_xlabel() == "time (CET, as the export's time stamps)"
    text = ax_pattern.texts[0].get_text()
    assert text.startswith("test votes: + stiction, - not stiction, . cannot tell\n")
    capsys.readouterr()


@pytest.mark.parametrize("unit", [("milliseconds", 1e3), ("microseconds", 1e6),
                                  ("nanoseconds", 1e9)], ids=["ms", "us", "ns"])
def test_unix_time_in_milliseconds_and_finer_is_read_as_seconds_and_said(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict, unit: tuple[str, float]) -> None:
    """A time column in Unix milliseconds (Ignition's t_stamp, most web historians) was
    read as seconds without a word: the period 1000 times too long (235,679 s for 235.7 s),
    and every time-based rule (enough to judge, --from/--to) off by as much."""
    word, per_second = unit
    start = int(UTC0.timestamp())
    t, op, pv = loop
    rows = [[str(round((start + float(a)) * per_second)), f"{b:.4f}", f"{c:.4f}"]
            for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path / "epoch.csv", ("t_stamp", "FIC101.OP", "FIC101.PV"), rows, ",")
    got = _run(capsys, path, "--time", "t_stamp", "--op", "FIC101.OP", "--pv", "FIC101.PV")
    _same(got, clean)
    said = [w for w in got["warnings"] if "Unix time" in w]
    assert said == [f"column 't_stamp' holds Unix time in {word} ({rows[0][0]!r} is "
                    f"{UTC0:%Y-%m-%d %H:%M:%S} UTC): read as seconds"]
    # a --from time is read as its column is: the stretch of the seconds export from the
    # same row
    cut = _run(capsys, path, "--time", "t_stamp", "--op", "FIC101.OP", "--pv", "FIC101.PV",
               "--from", rows[300][0])
    seconds = [(f"{a:g}", b, c) for a, (_, b, c) in zip(t, rows, strict=True)]
    in_seconds = _run(capsys, _write(tmp_path / "s.csv", ("t", "op", "pv"), seconds, ","),
                      "--from", seconds[300][0])
    assert cut["confidence"] != got["confidence"]  # a stretch, not the whole
    assert {k: v for k, v in cut.items() if k != "warnings"} == \
        {k: v for k, v in in_seconds.items() if k != "warnings"}


def test_spreadsheet_serial_dates_are_refused_naming_them(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        loop: tuple[np.ndarray, ...]) -> None:
    """Excel's date-times saved as numbers (days since 1899-12-30) were read as seconds and
    refused as 'time stamps irregular ... the historian exported recorded (compressed)
    values': the wrong cause and the wrong remedy."""
    t, op, pv = loop
    days = (UTC0 - dt.datetime(1899, 12, 30, tzinfo=dt.UTC)).total_seconds() / 86400
    rows = [[f"{days + float(a) / 86400:.8f}", f"{b:.4f}", f"{c:.4f}"]
            for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path / "excel.csv", HEADER, rows, ",")
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert f"column 'Time' holds numbers like {rows[0][0]!r} (line 2)" in err
    assert f"spreadsheet serial dates (days since 1899-12-30; {rows[0][0]!r} would be " \
        f"{UTC0:%Y-%m-%d %H:%M:%S})" in err
    assert "compressed" not in err


def test_rows_newest_first_are_read_oldest_first_and_said(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """An export written newest first was refused: 'time goes backwards ... sort the rows
    by time'. Time going back on every row is that order, not a fault."""
    _, rows = _export(tmp_path / "x.txt", loop, _iso)
    path = _write(tmp_path / "newest-first.txt", HEADER, rows[::-1], "\t")
    got = _quirk(capsys, path)
    _same(got, clean)
    assert f"rows newest first (column 'Time' from {rows[-1][0]!r} back to {rows[0][0]!r}): " \
        "read oldest first" in got["warnings"]
    # a stretch of it, by the file's own time, is the same stretch as in time order
    stretch = ("--from", rows[200][0], "--to", rows[900][0])
    in_order = _quirk(capsys, _write(tmp_path / "in-order.txt", HEADER, rows, "\t"), *stretch)
    assert {k: v for k, v in _quirk(capsys, path, *stretch).items() if k != "warnings"} == \
        {k: v for k, v in in_order.items() if k != "warnings"}
    # one row out of order is still refused, naming it
    swapped = [*rows[:10], rows[11], rows[10], *rows[12:]]
    err = _error(capsys, _write(tmp_path / "swapped.txt", HEADER, swapped, "\t"),
                 "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert "time goes backwards" in err and "sort the rows by time" in err


@pytest.mark.parametrize("form", [("%Y-%m-%d", "%H:%M:%S"), ("%d.%m.%Y", "%H:%M:%S"),
                                  ("%m/%d/%Y", "%I:%M:%S %p")],
                         ids=["iso", "german", "us-am-pm"])
def test_date_and_time_in_two_columns_are_read_together(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict, form: tuple[str, str]) -> None:
    """A spreadsheet export with the date and the time of day in two columns was refused:
    "not a time: '06:00:00' ... or give --ts S". Across midnight, so the date matters."""
    date, time = form
    t, op, pv = loop
    start = dt.datetime(2024, 3, 1, 23, 55)
    rows = [[(start + dt.timedelta(seconds=float(a))).strftime(date),
             (start + dt.timedelta(seconds=float(a))).strftime(time), f"{b:.4f}", f"{c:.4f}"]
            for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path / "split.csv", ("Date", "Time", "FIC101.OP", "FIC101.PV"), rows, ";")
    got = _quirk(capsys, path)
    _same(got, clean)
    assert "columns 'Date' and 'Time' read together as the time stamp" in got["warnings"]


def test_times_of_day_without_a_date_cross_midnight(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """Times of day alone (a trend copied from an operator screen): a day added at
    midnight, said so; they were refused as 'not a time'."""
    t, op, pv = loop
    start = dt.datetime(2024, 3, 1, 23, 55)
    rows = [[(start + dt.timedelta(seconds=float(a))).strftime("%H:%M:%S"), f"{b:.4f}",
             f"{c:.4f}"] for a, b, c in zip(t, op, pv, strict=True)]
    got = _quirk(capsys, _write(tmp_path / "times.csv", HEADER, rows, ","))
    _same(got, clean)
    assert any(w.startswith("column 'Time' holds times of day without a date") and
               "a day added each time the clock passes midnight" in w for w in got["warnings"])


def test_a_preamble_before_the_header_is_skipped_and_said(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        clean: dict) -> None:
    """Lines of metadata before the header (tag, server, export time) made the first of
    them the header: "no column 'FIC101.OP' (columns: Tag: FIC101)"."""
    path, _ = _export(tmp_path / "export.csv", loop, _iso, sep=";")
    text = path.read_text(encoding="utf-8")
    path.write_text("Tag: FIC101\r\nServer: PHD01\r\nExported: 2024-03-01 07:00\r\n\r\n" + text,
                    encoding="utf-8")
    got = _quirk(capsys, path)
    _same(got, clean)
    assert "lines 1-4 before the header hold no column (an export's preamble?): skipped " \
        "('Tag: FIC101', 'Server: PHD01', 'Exported: 2024-03-01 07:00')" in got["warnings"]
    # lines are still counted from the top of the file: data row k is line k + 3 under a
    # one-line preamble and the header
    rows = text.splitlines()
    rows[11], rows[12] = rows[12], rows[11]  # data rows 10 and 11 swapped
    path.write_text("Tag: FIC101\r\n" + "\r\n".join(rows) + "\r\n", encoding="utf-8")
    err = _error(capsys, path, "--op", "FIC101.OP", "--pv", "FIC101.PV")
    assert f"time goes backwards in column 'Time': {rows[11].split(';')[0]!r} (line 13) -> " \
        f"{rows[12].split(';')[0]!r} (line 14)" in err


def test_a_plot_of_unix_milliseconds_is_on_date_times(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], loop: tuple[np.ndarray, ...],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The plot's axis of a column in Unix milliseconds: date-times in UTC, not seconds
    labelled as the export's time (the export wrote milliseconds)."""
    figure = pytest.importorskip("matplotlib.figure")
    figures: list = []
    monkeypatch.setattr(figure.Figure, "savefig", lambda self, *a, **k: figures.append(self))
    t, op, pv = loop
    start = int(UTC0.timestamp())
    rows = [[str(round((start + float(a)) * 1000)), f"{b:.4f}", f"{c:.4f}"]
            for a, b, c in zip(t, op, pv, strict=True)]
    path = _write(tmp_path / "epoch.csv", ("t_stamp", "FIC101.OP", "FIC101.PV"), rows, ",")
    assert main(["analyze", str(path), "--time", "t_stamp", "--op", "FIC101.OP", "--pv",
                 "FIC101.PV", "--plot", str(tmp_path / "a.png")]) == 0
    ax_op, ax_pv, _ = figures[0].axes
    assert ax_op.lines[0].get_xdata()[0] == UTC0
    assert ax_pv.get_xlabel() == "time (UTC, as the export's time stamps)"
    capsys.readouterr()
