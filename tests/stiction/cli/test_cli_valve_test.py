"""`stiction valve-test`: a step test's recording read as a historian exports it, its
report as text and JSON, and the recordings it refuses (exit status 2, naming what a step
test needs)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from stiction import HeValve
from stiction.cli import main
from stiction.scenarios.steptest import simulate_step_test
from stiction.valvetest import step_test_levels

JSON_STEP_KEYS = {"op_step", "moved", "travel", "dead_time_s", "t63_s", "t86_s", "overshoot"}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A He valve (fs 3 %, fd 1 %: dead band 4 %, resolution 2 %) step-tested in manual,
    exported with date-times, ';' and decimal commas, its position beside PV."""
    run = simulate_step_test(HeValve(0.03, 0.01, 1.0), step_test_levels(), hold=30, tau=4.0,
                             theta=2.0, noise_sd=0.05, position_noise_sd=0.02, seed=2)
    path = tmp_path_factory.mktemp("valvetest") / "test.csv"
    lines = ["Timestamp;FV101.OP;FV101.PV;FV101.POS"]
    for i, (o, p, x) in enumerate(zip(run.op[0], run.pv[0], run.vp[0], strict=True)):
        stamp = f"2024-03-01 {6 + i // 3600:02d}:{i // 60 % 60:02d}:{i % 60:02d}"
        lines.append(";".join([stamp] + [f"{v:.4f}".replace(".", ",") for v in (o, p, x)]))
    path.write_text("\n".join(lines) + "\n")
    return path


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:  # type: ignore[type-arg]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    return json.loads(out)  # type: ignore[no-any-return]


def test_json_report_from_pv_and_from_position(recording: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    base = ["valve-test", str(recording), "--op", "FV101.OP", "--op-range", "0", "100",
            "--json"]
    for source in (["--pv", "FV101.PV"], ["--position", "fv101.pos"]):
        got = _json(capsys, [*base, *source])
        assert {"unit", "deadband", "resolution", "slip", "steps"} <= set(got)
        assert got["unit"] == "% of span"
        assert got["deadband"] == pytest.approx(4.0, abs=0.4)
        assert got["resolution"] == pytest.approx(2.0, abs=0.2)
        assert got["slip"] > 1.5
        assert len(got["steps"]) == step_test_levels().size - 1
        assert all(set(s) >= JSON_STEP_KEYS for s in got["steps"])
        moved = [s for s in got["steps"] if s["moved"]]
        assert moved and all(s["t63_s"] is not None for s in moved)
        assert all(s["dead_time_s"] is None for s in got["steps"] if not s["moved"])
    assert got["source"] == "position"
    # without --op-range: the same sizes in OP units (here OP is % already)
    got = _json(capsys, ["valve-test", str(recording), "--op", "FV101.OP", "--pv",
                         "FV101.PV", "--json"])
    assert got["unit"] == "OP units" and got["deadband"] == pytest.approx(4.0, abs=0.4)


def test_text_report_and_plot(recording: Path, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    plot = tmp_path / "test.png"
    assert main(["valve-test", str(recording), "--op", "FV101.OP", "--pv", "FV101.PV",
                 "--op-range", "0", "100", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "dead band:" in out and "% of span" in out and "resolution:" in out
    assert "T63 s" in out and f"wrote {plot}" in out
    assert plot.stat().st_size > 10_000


def _csv(tmp_path: Path, op: np.ndarray) -> Path:
    p = tmp_path / "r.csv"
    p.write_text("t,op,pv\n" + "".join(f"{i},{o:.4f},{50 + o / 10:.4f}\n"
                                       for i, o in enumerate(op)))
    return p


@pytest.mark.parametrize(("op", "why"), [
    (np.full(400, 40.0), "OP never steps"),
    (50 + 5 * np.sin(np.arange(400) / 9.0), "moves continuously"),
])
def test_no_step_test_is_refused_naming_what_one_needs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], op: np.ndarray, why: str) -> None:
    with pytest.raises(SystemExit) as info:
        main(["valve-test", str(_csv(tmp_path, op))])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert why in err and "manual" in err and "reversals" in err


def test_missing_column_names_the_option(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["valve-test", str(_csv(tmp_path, np.full(40, 1.0))), "--position", "vp"])
    assert info.value.code == 2
    assert "no column 'vp'" in capsys.readouterr().err


def test_simulate_writes_a_step_test_that_valve_test_reads(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "st.csv"
    assert main(["simulate", "--scenario", "table5-case1", "--fs", "0.02", "--fd", "0.01",
                 "--k", "1", "--noise", "0.02", "--step-test", "20", "-o", str(out)]) == 0
    assert "wrote 3960 samples" in capsys.readouterr().out  # 198 levels of 20 s
    assert out.read_text().splitlines()[0] == "t,op,pv,vp"
    got = _json(capsys, ["valve-test", str(out), "--position", "vp", "--op-range", "0",
                         "100", "--json"])
    assert got["deadband"] == pytest.approx(3.0, abs=0.3)  # fs + fd
    assert got["resolution"] == pytest.approx(1.0, abs=0.2)  # fs - fd
    got = _json(capsys, ["valve-test", str(out), "--op-range", "0", "100", "--json"])
    assert got["process"] == "integrating"  # a level loop, told from the data
    assert got["deadband"] == pytest.approx(3.0, abs=0.3)
    with pytest.raises(SystemExit):
        main(["simulate", "--scenario", "table4-case1", "--step-test", "3", "-o", str(out)])
    assert "--step-test: 3 s holds fewer than 5 samples" in capsys.readouterr().err


@pytest.fixture(scope="module")
def flow_test(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`stiction simulate`'s step test of a valve of fs 3 %, fd 1 % (K = 1) on a flow loop,
    60-s holds, as a new user writes it."""
    out = tmp_path_factory.mktemp("flow") / "fv101.csv"
    assert main(["simulate", "--scenario", "table4-case1", "--fs", "0.03", "--fd", "0.01",
                 "--k", "1", "--noise", "0.02", "--step-test", "60", "-o", str(out)]) == 0
    return out


def _edited(src: Path, dst: Path, pv: object) -> Path:
    """``src`` with its PV column replaced by ``pv(row, value)``."""
    lines = src.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    dst.write_text("\n".join([lines[0], *(",".join([r[0], r[1], f"{pv(i, float(r[2])):.6f}",
                                                     r[3]]) for i, r in enumerate(rows))])
                   + "\n")
    return dst


def test_kp_is_used_and_a_disturbed_hold_is_read_as_one(
        flow_test: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--kp gives the gain PV is read through; PV pushed by 1.5 while OP held (the hold at
    9000 s) is named, the steps beside it marked '?', and the figures stay the valve's."""
    got = _json(capsys, ["valve-test", str(flow_test), "--op-range", "0", "100", "--kp",
                         "1", "--json"])
    assert got["gain"] == pytest.approx(1.0)
    bumped = _edited(flow_test, tmp_path / "bumped.csv",
                     lambda i, v: v + (1.5 if 9020 <= i < 9045 else 0.0))
    assert main(["valve-test", str(bumped), "--op-range", "0", "100"]) == 0
    out = capsys.readouterr().out
    assert "cannot be read (?)" in out and "a disturbance, not the valve" in out
    assert "dead band:  4.02 % of span (3.84 .. 4.02)" in out
    assert any(line.split()[2:3] == ["?"] for line in out.splitlines()
               if line.strip().startswith("90"))
    with pytest.raises(SystemExit) as info:
        main(["valve-test", str(flow_test), "--position", "vp", "--kp", "1"])
    assert info.value.code == 2 and "--kp is PV's process gain" in capsys.readouterr().err


def test_a_frozen_pv_is_refused_not_read(flow_test: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A PV that holds one value while OP steps: exit 2, saying so (5c94178: '1 moved the
    valve', exit 0)."""
    frozen = _edited(flow_test, tmp_path / "frozen.csv", lambda i, v: 50.0)
    with pytest.raises(SystemExit) as info:
        main(["valve-test", str(frozen), "--op-range", "0", "100"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "PV holds one value (50) in all 11880 samples" in err and "frozen" in err
