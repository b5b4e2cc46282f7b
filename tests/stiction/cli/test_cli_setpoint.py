"""``stiction analyze`` reads the export's setpoint (issue 35 item 1): a column named sp,
setpoint or set point (any case) or given by ``--sp COL``, unless ``--no-sp``; the window is
then judged on its longest stretch between setpoint steps, the reason saying so; a
manifest's ``sp`` column names it per file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stiction.cli import main
from stiction.scenarios import scenario, simulate


@pytest.fixture(scope="module")
def export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A good valve under a sine load, a setpoint step of 8 at 1200 s, every 2 s."""
    sim = simulate(scenario("disturbance", sp_step=8.0, sp_step_time=300.0), noise=0.05,
                   duration=4800.0, seed=2)
    path = tmp_path_factory.mktemp("sp") / "fic.csv"
    rows = ["Time,OP,PV,Set Point"] + [f"{sim.t[i]:g},{sim.op[i]:.5f},{sim.pv[i]:.5f},"
                                        f"{sim.sp[i]:g}" for i in range(0, sim.op.size, 2)]
    path.write_text("\n".join(rows) + "\n")
    return path


def _reason(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main([*argv, "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert isinstance(got, dict)
    return str(got["reason"])


def test_the_setpoint_column_is_found_and_the_stretch_said(capsys, export: Path) -> None:
    reason = _reason(capsys, ["analyze", str(export)])
    assert "Judged on samples 150-2399" in reason  # 300 s at 2 s a sample
    assert "50 -> 58 at sample 150" in reason


def test_no_sp_judges_the_whole_window(capsys, export: Path) -> None:
    assert "Judged on samples" not in _reason(capsys, ["analyze", str(export), "--no-sp"])


def test_sp_names_another_column(capsys, export: Path, tmp_path: Path) -> None:
    other = tmp_path / "renamed.csv"
    other.write_text(export.read_text().replace("Set Point", "FIC101.SP", 1))
    assert "Judged on samples" not in _reason(capsys, ["analyze", str(other)])
    assert "Judged on samples 150-2399" in _reason(capsys, ["analyze", str(other), "--sp",
                                                          "fic101.sp"])
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(other), "--sp", "nope"])
    assert exc.value.code == 2
    assert "no column 'nope'" in capsys.readouterr().err


def test_a_manifest_sp_column(capsys, export: Path, tmp_path: Path) -> None:
    other = tmp_path / "renamed.csv"
    other.write_text(export.read_text().replace("Set Point", "SPX", 1))
    (tmp_path / "loops.csv").write_text(f"file,sp\n{other},spx\n{other},\n")
    assert main(["analyze", "--manifest", str(tmp_path / "loops.csv"), "--json",
                 "--sort", "file"]) == 0
    first, second = json.loads(capsys.readouterr().out)
    assert "Judged on samples 150-2399" in first["reason"]
    assert "Judged on samples" not in second["reason"]
