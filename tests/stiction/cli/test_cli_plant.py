"""`stiction plant` on a wide historian export of the hand-made plant with a sticky valve."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from plant_fixtures import plant_records, write_wide_export

from stiction.cli import main
from stiction.cli.plant import loop_columns


def _export(tmp_path: Path, **kw: dict[str, str]) -> Path:
    return write_wide_export(tmp_path / "unit.csv", plant_records()["sticky-feeds-two"], **kw)


def test_groups_sources_and_every_loop_in_text(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plant", str(_export(tmp_path)), "--integrating", "LIC301"]) == 0
    out = capsys.readouterr().out
    assert "group 1: period 1" in out and "source FIC101" in out
    assert "members: FIC101" in out and "TI205" in out
    assert "source ranking: FIC101" in out
    for tag in ("FIC101", "TIC201", "LIC301", "PIC401", "FIC102"):
        assert f"\n{tag}" in out or out.startswith(tag)


def test_json_has_groups_and_loops(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plant", str(_export(tmp_path)), "--integrating", "LIC301", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    (g,) = [g for g in data["groups"] if "FIC101" in g["loops"]]
    assert 140 < g["period_s"] < 200 and g["source"] == "FIC101"
    assert g["source_ranking"][0]["loop"] == "FIC101"
    assert all(set(r) >= {"loop", "score"} for r in g["source_ranking"])
    scores = [r["score"] for r in g["source_ranking"]]
    assert scores == sorted(scores, reverse=True)
    loops = {x["loop"]: x for x in data["loops"]}
    assert set(loops) == {"FIC101", "TIC201", "LIC301", "PIC401", "FIC102"}
    assert loops["FIC101"]["role"] == "source"
    assert loops["FIC101"]["verdict"] in ("stiction", "undetermined")
    assert loops["TIC201"]["role"] == "follower" and loops["TIC201"]["group"] == g["group"]
    assert all(set(x) >= {"loop", "verdict", "confidence", "group", "role"}
               for x in loops.values())


def test_the_spectral_map_is_drawn(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    png = tmp_path / "map.png"
    assert main(["plant", str(_export(tmp_path)), "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("header", "loops", "indicators"), [
    (["FIC1.OP", "FIC1.PV", "TI9"], {"FIC1": (0, 1)}, {"TI9": 2}),
    (["fic1_op", "FIC1_PV", "fic1.sp"], {"fic1": (0, 1)}, {}),
    (["A.MV", "A.PV", "B.OUT", "B pv", "C.OP"], {"A": (0, 1), "B": (2, 3)}, {"C.OP": 4}),
])
def test_loops_are_found_from_column_pairs(header: list[str], loops: dict[str, tuple[int, int]],
                                           indicators: dict[str, int]) -> None:
    found, others = loop_columns(header)
    assert {k.lower(): v for k, v in found.items()} == {k.lower(): v for k, v in loops.items()}
    assert others == indicators


def test_bad_input_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / "x.csv"
    csv.write_text("t,TI1,TI2\n0,1,2\n1,2,3\n")
    with pytest.raises(SystemExit) as exc:
        main(["plant", str(csv)])
    assert exc.value.code == 2
    assert "no loop found: name the columns TAG.OP and TAG.PV" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--integrating", "LIC999"])
    assert "no loop 'LIC999' in the file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--cascade", "TIC201"])
    assert "--cascade 'TIC201': give OUTER=INNER" in capsys.readouterr().err
