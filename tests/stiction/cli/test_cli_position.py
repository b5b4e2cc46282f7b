"""``stiction analyze --position COL`` (issue 30 item 1): with the valve's travel in the
export, stiction is measured from it (band and slip beside fd and fs), on the file's own
grid and stretch; a manifest's ``position`` column does the same per file; without the
option the file is analysed from OP and PV as before."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from valve_loops import run_loops

from stiction.cli import main
from stiction.diagnosis.travel import MEASURED
from stiction.models.valves import KanoValve


@pytest.fixture(scope="module")
def export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A sticky Kano valve (band 5 %, slip 1 %), its position read, every 2 s with a row
    missing: the grid must keep the three columns aligned."""
    (r,) = run_loops(KanoValve(0.05, 0.01), 1, pv_noise=0.05, position_noise=0.05)
    path = tmp_path_factory.mktemp("pos") / "fic.csv"
    rows = ["t,op,pv,pos"] + [f"{i},{r.op[i]:.5f},{r.pv[i]:.5f},{r.position[i]:.5f}"
                             for i in range(0, r.op.size) if i != 1001]
    path.write_text("\n".join(rows) + "\n")
    return path


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> object:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_the_position_column_measures_band_and_slip(capsys, export: Path) -> None:
    got = _json(capsys, ["analyze", str(export), "--position", "pos", "--op-range", "0", "100",
                         "--json"])
    assert isinstance(got, dict)
    assert got["verdict"] == "stiction"
    assert MEASURED in got["reason"]
    assert got["size"]["band"] == pytest.approx(5.0, rel=0.1)
    assert got["size"]["slip"] == pytest.approx(1.0, rel=0.1)
    assert "band" not in got and "band_op" not in got  # sizes only under `size`
    assert main(["analyze", str(export), "--position", "pos", "--op-range", "0", "100"]) == 0
    text = capsys.readouterr().out
    assert "band: " in text and "slip: " in text


def test_without_the_option_op_and_pv_decide(capsys, export: Path) -> None:
    got = _json(capsys, ["analyze", str(export), "--op-range", "0", "100", "--json"])
    assert isinstance(got, dict)
    assert MEASURED not in got["reason"]
    assert got["size"] is None or got["size"].get("band") is None


def test_a_manifest_position_column(capsys, export: Path, tmp_path: Path) -> None:
    (tmp_path / "loops.csv").write_text(f"file,position\n{export},pos\n{export},\n")
    got = _json(capsys, ["analyze", "--manifest", str(tmp_path / "loops.csv"), "--op-range",
                         "0", "100", "--json"])
    assert isinstance(got, list) and len(got) == 2
    assert MEASURED in got[0]["reason"] and got[0]["size"]["band"] == pytest.approx(5.0,
                                                                                  rel=0.1)
    assert MEASURED not in got[1]["reason"]


def test_a_missing_position_column_is_named(capsys, export: Path) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(export), "--position", "travel"])
    assert exc.value.code == 2
    assert "no column 'travel'" in capsys.readouterr().err


def test_the_stretch_cuts_the_position_with_op_and_pv(capsys, export: Path) -> None:
    got = _json(capsys, ["analyze", str(export), "--position", "pos", "--op-range", "0", "100",
                         "--from", "1000", "--to", "3999", "--json"])
    assert isinstance(got, dict)
    assert got["verdict"] == "stiction" and MEASURED in got["reason"]
    assert np.isfinite(got["size"]["band"])
