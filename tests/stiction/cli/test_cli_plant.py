"""`stiction plant` on a wide historian export of the hand-made plant with a sticky valve,
and `stiction simulate --plant` writing one."""

from __future__ import annotations

import contextlib
import csv
import functools
import io
import json
import re
from pathlib import Path
from typing import Any

import pytest
from plant_fixtures import plant_records, write_wide_export

from stiction.cli import main
from stiction.cli.plant import loop_columns
from stiction.scenarios.plant import PlantRecord, simulate_plants
from stiction.scenarios.plants import NAMED_PLANTS


def _export(tmp_path: Path, **kw: dict[str, str]) -> Path:
    return write_wide_export(tmp_path / "unit.csv", plant_records()["sticky-feeds-two"], **kw)


def test_groups_sources_and_every_loop_in_text(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plant", str(_export(tmp_path)), "--integrating", "LIC301"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    # the count agrees with the members listed: loops and indicators apart (the cycle's
    # period is 150-215 s over 40 realisations of the plant: machines differ in which)
    (h,) = [k for k, ln in enumerate(lines) if ln.startswith("group ") and "FIC101" in ln]
    head, loops = lines[h], lines[h + 1]
    assert re.match(r"group \d: period (1\d\d|2[0-4]\d) s, 3 loops and 1 indicator, ", head)
    assert "source FIC101 (named by " in head and loops.startswith("  loops: ")
    assert sorted(x.split()[0] for x in loops[9:].split(", ")) == ["FIC101", "LIC301",
                                                                    "TIC201"]
    assert lines[h + 2].startswith("  indicators: TI205 ")
    # the ranking with a header and every evidence's figure, then the legend of each
    i = lines.index("  source ranking:", h)
    assert lines[i + 1].split() == ["loop", "score", "own", "verdict", "valve", "Granger",
                                    "NLI", "lag", "s"]
    assert lines[i + 2].split()[0] == "FIC101"
    assert "(score: the rank" in out and "NLI: nonlinearity index" in out
    # the loop table: a header, each loop once, the confidence explained
    (table,) = [k for k, ln in enumerate(lines) if ln.startswith("loop ")]
    assert lines[table].split()[:5] == ["loop", "verdict", "confidence", "plant", "role"]
    tags = [ln.split()[0] for ln in lines[table + 1:table + 6]]
    assert tags == ["FIC101", "TIC201", "LIC301", "PIC401", "FIC102"]
    assert "(confidence: the per-loop analysis' confidence" in out


def test_json_has_groups_evidence_and_loops(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plant", str(_export(tmp_path)), "--integrating", "LIC301", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    (g,) = [g for g in data["groups"] if "FIC101" in g["loops"]]
    assert 120 < g["period_s"] < 250 and g["source"] == "FIC101"
    assert "direction" in g["named_by"] and g["entry"] is None
    assert g["indicators"] == ["TI205"] and len(g["loops"]) == 3
    top = g["source_ranking"][0]
    assert top["loop"] == "FIC101" and top["granger_flow"] > 0.2 and top["nli"] > 1.0
    assert set(top) >= {"loop", "score", "verdict", "confidence", "valve_gain", "valve",
                        "granger_flow", "nli", "lag_s", "harmonics"}
    scores = [r["score"] for r in g["source_ranking"]]
    assert scores == sorted(scores, reverse=True)
    loops = {x["loop"]: x for x in data["loops"]}
    assert set(loops) == {"FIC101", "TIC201", "LIC301", "PIC401", "FIC102"}
    assert loops["FIC101"]["role"] == "source"
    assert loops["TIC201"]["role"] == "follower" and loops["TIC201"]["group"] == g["group"]
    assert all(set(x) >= {"loop", "verdict", "confidence", "group", "role"}
               for x in loops.values())
    assert data["left_out"] == {}


def test_the_spectral_map_marks_the_groups_and_has_a_colour_scale(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    from stiction.cli import plant as plant_cli  # noqa: PLC0415

    drawn: list[list[str]] = []
    real = plant_cli.spectral_map
    monkeypatch.setattr(plant_cli, "spectral_map",
                        lambda *a, **k: drawn.append(real(*a, **k)) or [])
    png = tmp_path / "map.png"
    assert main(["plant", str(_export(tmp_path)), "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert drawn[0][0] == "share of the loop's power (log10)"
    assert any(re.fullmatch(r"group \d: source FIC101", x) for x in drawn[0])


@functools.cache
def _two_units() -> tuple[PlantRecord, PlantRecord]:
    """The sticky plant twice, two seeds: two units whose valves cycle at one period."""
    a, b = simulate_plants([NAMED_PLANTS["sticky-feeds-two"]] * 2, duration=7200.0, seed=11)
    return a, b


def _write_two_units(path: Path) -> Path:
    a, b = _two_units()
    cols = {f"U{k}.{n}.{s}": (r.op if s == "OP" else r.pv)[n]
            for k, r in ((1, a), (2, b)) for n in r.op for s in ("OP", "PV")}
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *cols])
        for i in range(next(iter(cols.values())).size):
            w.writerow([i, *(f"{v[i]:.4f}" for v in cols.values())])
    return path


def test_two_units_at_one_period_are_two_groups(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    csv_path = _write_two_units(tmp_path / "two.csv")
    assert main(["plant", str(csv_path), "--json"]) == 0
    one = json.loads(capsys.readouterr().out)["groups"]
    (mixed,) = [g for g in one if "U1.FIC101" in g["loops"]]
    assert "U2.FIC101" in mixed["loops"]  # without units: one group across both
    assert main(["plant", str(csv_path), "--json", "--unit-prefix"]) == 0
    groups = json.loads(capsys.readouterr().out)["groups"]
    by_source = {g["source"]: g for g in groups if g["source"]}
    assert {"U1.FIC101", "U2.FIC101"} <= set(by_source)
    assert not any(x.startswith("U2.") for x in by_source["U1.FIC101"]["loops"])
    assert not any(x.startswith("U1.") for x in by_source["U2.FIC101"]["loops"])


def test_units_are_named_by_a_map_or_by_the_tags_prefix() -> None:
    from argparse import Namespace  # noqa: PLC0415

    from stiction.cli.plant import _units  # noqa: PLC0415

    loops = dict.fromkeys(["U1.FIC101", "U1.TIC201", "U2.FIC101", "FIC9"])
    inds = dict.fromkeys(["U1/TI205", "TI9"])
    assert _units(Namespace(unit_prefix=True, units=[]), loops, inds) == {
        "U1.FIC101": "U1", "U1.TIC201": "U1", "U2.FIC101": "U2", "U1/TI205": "U1"}
    assert _units(Namespace(unit_prefix=False, units=["A=u1.fic101,TI9", "B=FIC9"]), loops,
                  inds) == {"U1.FIC101": "A", "TI9": "A", "FIC9": "B"}


def test_simulate_writes_a_plant_export_that_plant_reads(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plant.csv"
    assert main(["simulate", "--plant", "sticky-feeds-two", "--ts", "2", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert said.startswith("wrote 3600 samples (7200 s, every 2 s) of plant sticky-feeds-two")
    assert "5 loops, 1 indicator; try: stiction plant" in said
    header = out.read_text().splitlines()[0].split(",")
    assert header[:3] == ["t", "FIC101.OP", "FIC101.PV"] and header[-1] == "TI205"
    assert main(["plant", str(out), "--integrating", "LIC301", "--json"]) == 0
    (g,) = [g for g in json.loads(capsys.readouterr().out)["groups"] if "FIC101" in g["loops"]]
    assert g["source"] == "FIC101"
    for bad, why in ((["--fs", "0.1"], "--plant takes --duration, --ts and --seed only, not "
                                       "--fs"),
                     (["--ts", "0.5"], "--ts 0.5: a plant's export is sampled every whole")):
        with pytest.raises(SystemExit):
            main(["simulate", "--plant", "sticky-feeds-two", *bad, "-o", str(out)])
        assert why in capsys.readouterr().err


@pytest.mark.parametrize(("header", "loops", "indicators"), [
    (["FIC1.OP", "FIC1.PV", "TI9"], {"FIC1": (0, 1)}, {"TI9": 2}),
    (["fic1_op", "FIC1_PV", "fic1.sp"], {"fic1": (0, 1)}, {}),
    (["A.MV", "A.PV", "B.OUT", "B pv", "C.OP"], {"A": (0, 1), "B": (2, 3)}, {"C.OP": 4}),
    # historians' tag paths (issue 35): Ignition's provider left out of the name, a colon,
    # DeltaV's function block and .CV, a provider kept where two loops would be one
    (["[default]U2/FIC101/OP", "[default]U2/FIC101/PV", "[default]U2/TI205"],
     {"U2/FIC101": (0, 1)}, {"U2/TI205": 2}),
    (["U2:FIC1:PV", "U2:FIC1:OP"], {"U2:FIC1": (1, 0)}, {}),
    (["FIC1/PID1/OUT.CV", "FIC1/PID1/PV.CV", "FIC1/PID1/SP.CV"], {"FIC1/PID1": (0, 1)}, {}),
    (["[a]X/OP", "[a]X/PV", "[b]X/OP", "[b]X/PV"], {"[a]X": (0, 1), "[b]X": (2, 3)}, {}),
])
def test_loops_are_found_from_column_pairs(header: list[str], loops: dict[str, tuple[int, int]],
                                           indicators: dict[str, int]) -> None:
    found, others = loop_columns(header)
    assert {k.lower(): v for k, v in found.items()} == {k.lower(): v for k, v in loops.items()}
    assert others == indicators


def test_bad_input_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv_path = tmp_path / "x.csv"
    csv_path.write_text("t,TI1,TI2\n0,1,2\n1,2,3\n")
    with pytest.raises(SystemExit) as exc:
        main(["plant", str(csv_path)])
    assert exc.value.code == 2
    assert "no loop found: name the columns TAG.OP and TAG.PV" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--integrating", "LIC999"])
    assert "no loop 'LIC999' in the file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--cascade", "TIC201"])
    assert "--cascade 'TIC201': give OUTER=INNER" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--units", "A=FIC101,XIC9"])
    assert "--units 'A=FIC101,XIC9': no loop or indicator 'XIC9' in the file" in \
        capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["plant", str(_export(tmp_path)), "--units", "FIC101"])
    assert "--units 'FIC101': give UNIT=TAG,TAG,..." in capsys.readouterr().err


def test_an_export_newest_first_reads_as_in_time_order(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A plant export written newest first was refused ('time goes backwards'); it gives
    what the export in time order gives, with one warning more."""
    path = _export(tmp_path)
    lines = path.read_text().splitlines()
    reversed_path = tmp_path / "newest-first.csv"
    reversed_path.write_text("\n".join([lines[0], *lines[:0:-1]]) + "\n")
    assert main(["plant", str(path), "--integrating", "LIC301", "--json"]) == 0
    in_order = json.loads(capsys.readouterr().out)
    assert main(["plant", str(reversed_path), "--integrating", "LIC301", "--json"]) == 0
    newest_first = json.loads(capsys.readouterr().out)
    said = [w for w in newest_first.pop("warnings") if w not in in_order.pop("warnings")]
    assert len(said) == 1 and said[0].startswith("rows newest first (column 'Timestamp' from")
    assert newest_first == in_order
    assert in_order["groups"]  # a real answer: the sticky valve's group


def test_an_ignition_export_reads_its_tag_paths_as_loops(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 35: columns named as Ignition exports them ([default]U2/FIC101/OP) were all
    indicators; they are the loops they name, and the answer is the plain export's."""
    rec = plant_records()["sticky-feeds-two"]
    names = {f"{t}.{k}": f"[default]U2/{t}/{k}" for t in rec.op for k in ("OP", "PV")}
    path = write_wide_export(tmp_path / "ignition.csv", rec, names=names)
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0].replace(";TI205", ";[default]U2/TI205"),
                               *lines[1:]]) + "\n")
    assert main(["plant", str(path), "--integrating", "LIC301", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert main(["plant", str(_export(tmp_path)), "--integrating", "LIC301", "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert [x["loop"] for x in data["loops"]] == [f"U2/{x['loop']}" for x in plain["loops"]]
    (g,) = [g for g in data["groups"] if "U2/FIC101" in g["loops"]]
    (p,) = [g for g in plain["groups"] if "FIC101" in g["loops"]]
    assert g["source"] == "U2/FIC101" and g["entry"] is None
    assert g["loops"] == [f"U2/{x}" for x in p["loops"]] and g["indicators"] == ["U2/TI205"]
    assert {x["loop"]: x["verdict"] for x in data["loops"]} == \
        {f"U2/{x['loop']}": x["verdict"] for x in plain["loops"]}


def test_a_column_named_like_a_loops_signal_without_its_partner_is_warned_of(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _export(tmp_path)
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0] + ";[default]U2/FIC9/OP",
                               *(ln + ";1,5" for ln in lines[1:])]) + "\n")
    assert main(["plant", str(path), "--integrating", "LIC301", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert "column '[default]U2/FIC9/OP' is named like a loop's OP but the file has no PV " \
           "column of '[default]U2/FIC9': read as an indicator" in data["warnings"]


@functools.cache
def _historian_export(tmp: Path, ts: int, seed: int) -> Path:
    out = tmp / f"sfw-{ts}-{seed}.csv"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["simulate", "--plant", "sticky-feeds-two", "--ts", str(ts), "--duration",
                     "14400", "--seed", str(seed), "-o", str(out)]) == 0
    return out


@pytest.mark.parametrize(("ts", "seed"), [(30, 1), (30, 2), (60, 1), (60, 2)])
def test_a_historian_export_finds_the_group_and_tells_one_story(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        ts: int, seed: int) -> None:
    """Issue 37's acceptance: sticky-feeds-two exported at 30 and 60 s (a cycle of 5 and
    2.7 samples), as a new user would (`stiction simulate --plant sticky-feeds-two --ts N
    --duration 14400 --seed S`, `stiction plant --integrating LIC301`). On 5c94178 at 60 s
    no group was found and TIC201 and LIC301 (good valves) read stiction; at 30 s TIC201
    was a second source in the loop table and on the plot (two rings) while the JSON named
    FIC101. The group is found with FIC101 its source, TIC201 and LIC301 are not stiction,
    and the JSON, the text's loop table and the plot name that one source. (Seeds 1-5 at
    both rates: bench/_caselist/plant.py, case 37.sfw.)"""
    path = _historian_export(tmp_path, ts, seed)
    rings = _rings(monkeypatch)
    assert main(["plant", str(path), "--integrating", "LIC301", "--json", "--plot",
                 str(tmp_path / "map.png")]) == 0
    data = json.loads(capsys.readouterr().out)
    loops = {x["loop"]: x for x in data["loops"]}
    (g,) = [g for g in data["groups"] if g["group"] == loops["FIC101"]["group"]]
    assert {"FIC101", "TIC201", "LIC301"} <= set(g["loops"]) and 140 < g["period_s"] < 250
    assert g["source"] == "FIC101" and g["entry"] is None
    assert loops["TIC201"]["verdict"] != "stiction" and loops["LIC301"]["verdict"] != "stiction"
    named = {n for h in data["groups"] for n in (h["source"], *h["also_sources"]) if n}
    sources = sorted(n for n, x in loops.items() if x["role"] == "source")
    # JSON groups, JSON roles, the plot (at 60 s a second, slower group may hold FIC101 too)
    assert named == set(rings) == {"FIC101"} and sources == ["FIC101"]
    assert not [n for n, x in loops.items() if x["role"] == "follower"
                and x["verdict"] == "stiction"]
    assert main(["plant", str(path), "--integrating", "LIC301"]) == 0
    lines = capsys.readouterr().out.splitlines()
    (head,) = [k for k, ln in enumerate(lines) if ln.startswith("loop ")]
    roles = {ln.split()[0]: ln.split()[3:6] for ln in lines[head + 1:head + 6]}
    assert [n for n, r in roles.items() if r[:1] == ["group"] and r[2] == "source"] == \
        ["FIC101"]  # the text's loop table


def _rings(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The loops the spectral map will ring as sources (red circles), as drawn."""
    pytest.importorskip("matplotlib")
    from matplotlib.axes import Axes  # noqa: PLC0415

    rings: list[str] = []
    scatter = Axes.scatter

    def spy(self: Axes, x: Any, y: Any, *a: Any, **k: Any) -> Any:
        if k.get("edgecolors") == "r":
            rings.extend(self.get_yticklabels()[int(v)].get_text() for v in y)
        return scatter(self, x, y, *a, **k)

    monkeypatch.setattr(Axes, "scatter", spy)
    return rings
