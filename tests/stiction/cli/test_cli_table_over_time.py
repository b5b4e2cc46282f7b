"""What the batch table and the text output show an engineer (issue 38 item 11): the reason
whole where stdout is no terminal, with its caveats (it was cut to ~30 characters and lost
"too fast to see its shape: sample faster"); wrapped, not cut, on a terminal; periods and
flags in words, not `7.568e+04` and `oscillating: False` beside `undetermined`; and
`--every DURATION`: one verdict per window, a table over time."""

from __future__ import annotations

import datetime as dt
import io
import json
import re
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pytest

from stiction import Assessment, Verdict
from stiction.cli import main
from stiction.scenarios import scenario, simulate

START = dt.datetime(2024, 3, 1, 0, 0, 0)


def _out(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def fast(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A good valve under a 5-minute load exported at 1 minute, in a folder of a long name
    (as a plant's share is): its reason ends "too fast to see its shape: sample faster"."""
    res = simulate(scenario("disturbance", dist_period=300.0), noise=0.05, duration=28800.0,
                   seed=1)
    folder = tmp_path_factory.mktemp("unit") / "site-north" / "unit-4-crude-distillation"
    folder.mkdir(parents=True)
    path = folder / "FIC4711-feed-flow-controller.csv"
    np.savetxt(path, np.column_stack([res.t, res.op, res.pv])[::60], delimiter=",",
               header="t,op,pv", comments="", fmt="%.4f")
    return path


def test_not_on_a_terminal_the_reason_is_whole(capsys: pytest.CaptureFixture[str],
                                               fast: Path) -> None:
    out = _out(capsys, "analyze", str(fast), str(fast))
    rows = [re.sub(r"^\s*\d+\s+", "", line) for line in out.splitlines()]  # the rank off
    rows = [row for row in rows if row.startswith(str(fast))]
    assert len(rows) == 2
    for row in rows:
        assert row.endswith("The cycle of 5.0 samples is too fast to see its shape: sample "
                            "faster."), row
        assert "..." not in row
    assert "what each verdict means:" in out


def test_on_a_terminal_the_reason_wraps_under_its_column(fast: Path,
                                                         monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    """On a terminal 100 wide: every line fits, and the reason's words are all there."""
    buf = io.StringIO()
    monkeypatch.setattr(buf, "isatty", lambda: True, raising=False)
    monkeypatch.setenv("COLUMNS", "140")
    with redirect_stdout(buf):
        assert main(["analyze", str(fast), str(fast), "--every", "4h"]) == 0
    lines = buf.getvalue().splitlines()
    table = lines[:lines.index("what each verdict means:")]
    assert max(len(line) for line in table) <= 140
    words = " ".join(" ".join(table).split())
    assert words.count("too fast to see its shape: sample faster.") == 4  # 2 files x 2


def test_periods_and_flags_are_words(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                     ) -> None:
    """A sticky loop's file at 100 s a sample (a week is 6,048 rows): its period, some 22,600
    s, was printed `2.26e+04`; now `22650 s (6.29 h)`. Flags are yes or no."""
    res = simulate(scenario("table4-case2"), noise=0.02, seed=1, duration=3600.0)
    path = tmp_path / "slow.csv"
    np.savetxt(path, np.column_stack([res.op, res.pv]), delimiter=",", header="op,pv",
               comments="", fmt="%.4f")
    out = _out(capsys, "analyze", str(path), "--ts", "100")
    (period,) = [line for line in out.splitlines() if line.startswith("  period_s:")]
    assert re.fullmatch(r"  period_s: 2\d{4} s \(6\.\d\d h\)", period), period
    assert "e+0" not in out
    assert "  multi_jump: no" in out and "  oscillating: yes, a regular cycle" in out


def test_not_oscillating_is_not_false_beside_undetermined() -> None:
    from stiction.cli.analyze import _print  # noqa: PLC0415
    from stiction.cli.loop import view  # noqa: PLC0415

    a = Assessment(Verdict.UNDETERMINED, "undetermined, confidence of stiction 0.62: between "
                   "what the tests tell apart.", oscillating=False, confidence=0.62)
    buf = io.StringIO()
    with redirect_stdout(buf):
        _print(a, view(a))
    assert "False" not in buf.getvalue()
    assert "  oscillating: no regular cycle (the verdict judged an irregular one)" in \
        buf.getvalue()


@pytest.fixture(scope="module")
def three_days(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three days at 10 s from midnight, `;`-separated with ISO stamps: a sticky valve,
    then the valve repaired (a good one), then sticky again."""
    path = tmp_path_factory.mktemp("trend") / "fic101.csv"
    lines = ["Timestamp;FIC101.OP;FIC101.PV"]
    k = 0
    for name, seed in (("table4-case2", 1), ("healthy", 2), ("table4-case2", 3)):
        r = simulate(scenario(name), noise=0.05, seed=seed, duration=86400.0)
        for o, p in zip(r.op[::10], r.pv[::10], strict=True):
            lines.append(f"{START + dt.timedelta(seconds=10 * k):%Y-%m-%d %H:%M:%S};"
                         f"{o:.4f};{p:.4f}")
            k += 1
    path.write_text("\n".join(lines) + "\n")
    return path


ARGS = ("--op", "FIC101.OP", "--pv", "FIC101.PV")


def test_every_day_a_verdict(capsys: pytest.CaptureFixture[str], three_days: Path) -> None:
    """A three-day export gave one verdict; --every 1d gives one a day, each as --from/--to
    of that day gives it, in a table over time and in the JSON and CSV."""
    got = json.loads(_out(capsys, "analyze", str(three_days), *ARGS, "--every", "1d",
                          "--json"))
    assert [(g["from"], g["to"]) for g in got] == [
        (f"2024-03-0{d} 00:00:00", f"2024-03-0{d} 23:59:50") for d in (1, 2, 3)]
    assert [g["verdict"] for g in got] == ["stiction", "not_oscillating", "stiction"]
    for g in got:
        alone = json.loads(_out(capsys, "analyze", str(three_days), *ARGS, "--from", g["from"],
                                "--to", g["to"], "--json"))
        assert {k: v for k, v in g.items() if k not in ("file", "from", "to")} == alone
    text = _out(capsys, "analyze", str(three_days), *ARGS, "--every", "8h")
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["from", "to", "verdict"]
    assert [line.split()[4] for line in lines[1:10]] == ["stiction"] * 3 + \
        ["not_oscillating"] * 3 + ["stiction"] * 3
    assert lines[10] == "what each verdict means:"


def test_a_window_at_either_end_shorter_than_half_is_left_out(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], three_days: Path) -> None:
    """From 20:00 on the first day: its 4 h are less than half a day, left out, said so."""
    got = _out(capsys, "analyze", str(three_days), *ARGS, "--every", "1d", "--from",
               "2024-03-01 20:00:00")
    lines = got.splitlines()
    assert [line.split()[0] for line in lines[1:3]] == ["2024-03-02", "2024-03-03"]
    assert "warning: the first 4 h ('2024-03-01 20:00:00' to '2024-03-01 23:59:50'): less " \
        "than half a window: not analysed" in lines


def test_a_window_too_large_for_memory_is_refused_with_the_way_round(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        three_days: Path) -> None:
    """Issue 38 item 6: a year at 1 s would have needed ~20 GB, with no warning. The analysis
    holds ~320 bytes a sample: where the window's need passes what is free, it is refused,
    naming --every; a day at a time fits."""
    from stiction.cli import memory  # noqa: PLC0415

    monkeypatch.setattr(memory, "available", lambda: 6_000_000)  # 6 MB free
    with pytest.raises(SystemExit) as info:
        main(["analyze", str(three_days), *ARGS])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "one window of 25,920 samples (3 days at 10 s): its analysis needs about 0.0 GB " \
        "(320 bytes a sample), more than the 0.0 GB free; give --every 1d" in err
    got = json.loads(_out(capsys, "analyze", str(three_days), *ARGS, "--every", "1d", "--json"))
    assert [g["verdict"] for g in got] == ["stiction", "not_oscillating", "stiction"]


@pytest.mark.parametrize(("text", "seconds"), [("8h", 28800.0), ("1d", 86400.0),
                                               ("30min", 1800.0), ("90s", 90.0),
                                               ("1h30min", 5400.0), ("1w", 604800.0),
                                               ("600", 600.0)])
def test_durations(text: str, seconds: float) -> None:
    from stiction.cli.every import duration  # noqa: PLC0415

    assert duration(text) == seconds
