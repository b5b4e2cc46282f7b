"""Tag lists (issue 16): ``loops_csv:`` and ``stiction-gateway import-tags``. A row reads as
the YAML loop it stands for; every bad row is reported at once with its line; the 500-row
acceptance list (5 bad rows) imports to 495 loops that check-config takes in under 2 s."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from gateway.config import load_config, parse_config
from gateway.config.tagimport import import_tags
from gateway.config.tags import COLUMNS, read_tag_text
from gateway.errors import ConfigError

CLI = [sys.executable, "-m", "gateway.cli"]
BASE = """\
devices:
  - {name: plc1, protocol: modbus, host: 10.0.0.1}
  - {name: plc2, protocol: modbus, host: 10.0.0.2, unit_id: 3, poll_interval_s: 2}
  - {name: dcs1, protocol: opcua, endpoint: "opc.tcp://10.0.0.3:4840"}
"""


def write(tmp: Path, name: str, text: str) -> Path:
    path = tmp / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_row_is_the_yaml_loop_it_stands_for(tmp_path: Path) -> None:
    write(tmp_path, "tags.csv",
          "name,device,op,pv,type,pv_type,table,op_scale,op_offset,pv_scale,pv_offset,"
          "process,kp,delay_s,window_s,result_address,result_unit_id\n"
          "LIC201,plc1,100,101,int16,uint16,input,0.01,0,0.1,-50,integrating,0.2,1,3600,20,2\n"
          "TIC205,dcs1,ns=2;s=TIC205.OP,ns=2;s=TIC205.PV,,,,,,,,,,,,,\n")
    from_csv = load_config(write(tmp_path, "gw.yaml", BASE + "loops_csv: tags.csv\n"))
    from_yaml = parse_config(yaml.safe_load(BASE + """
loops:
  - {name: LIC201, device: plc1, process: integrating, kp: 0.2, delay_s: 1, window_s: 3600,
     op: {address: 100, type: int16, table: input, scale: 0.01, offset: 0},
     pv: {address: 101, type: uint16, table: input, scale: 0.1, offset: -50},
     result_address: 20, result_unit_id: 2}
  - {name: TIC205, device: dcs1, op: {node: "ns=2;s=TIC205.OP"}, pv: {node: "ns=2;s=TIC205.PV"}}
"""), "gw.yaml")
    assert from_csv.loops == from_yaml.loops
    assert from_csv.assigned == from_yaml.assigned == ("TIC205",)


def test_spreadsheet_exports_read_alike() -> None:
    """Semicolons or tabs, a byte-order mark, upper-case headers, quoted cells, comments
    and empty lines."""
    want = read_tag_text("name,device,op,pv,type\nA,plc1,0,2,float32\nB,plc1,4,6,int16\n",
                         "t.csv")
    for text in ("\ufeffName;Device;OP;PV;Type\r\nA;plc1;0;2;float32\r\n\r\nB;plc1;4;6;int16\r\n",
                 "# DCS export\nname\tdevice\top\tpv\ttype\nA\tplc1\t0\t2\tfloat32\n"
                 "# a comment\nB\tplc1\t4\t6\tint16\n",
                 'name,device,op,pv,type\n"A",plc1,0,2,float32\nB,"plc1",4,6, int16 \n'):
        got = read_tag_text(text.replace("\ufeff", ""), "t.csv")
        assert [r.cells for r in got.rows] == [r.cells for r in want.rows]
        assert got.file_problems == []


def test_yaml_loops_come_first_then_each_list_in_order(tmp_path: Path) -> None:
    (tmp_path / "area").mkdir()
    write(tmp_path, "area/one.csv", "name,device,op,pv,type\nB,plc1,0,2,float32\n")
    write(tmp_path, "two.csv", "name,device,op,pv,type\nC,plc1,4,6,float32\n")
    path = write(tmp_path, "gw.yaml", BASE + "loops_csv: [area/one.csv, two.csv]\nloops:\n"
                 "  - {name: A, device: plc1, op: {address: 8, type: int16}, "
                 "pv: {address: 9, type: int16}}\n")
    c = load_config(path)  # relative to the config's folder, wherever the caller is
    assert [(lp.name, lp.result_address) for lp in c.loops] == [("A", 0), ("B", 20), ("C", 40)]


def test_every_column_is_documented() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "configuration.md").read_text()
    for col in COLUMNS:
        assert f"| `{col}` |" in doc, col


# ------------------------------------------------------------------ 500 rows, 5 bad

BAD = {  # data row (1-based) -> what is wrong with it
    37: ("type", "flaot32"),
    120: ("device", "plc7"),
    250: ("op", "40x"),
    333: ("name", "FIC0002"),  # a duplicate
    499: ("window_s", "10"),  # 10 samples of plc1 (1 s)
}


def tag_list_500() -> str:
    lines = ["name,device,op,pv,type,window_s"]
    for k in range(1, 501):
        cells = {"name": f"FIC{k:04d}", "device": "plc1" if k % 2 else "plc2",
                 "op": str(4 * k), "pv": str(4 * k + 2), "type": "float32", "window_s": ""}
        if k in BAD:
            col, value = BAD[k]
            cells[col] = value
        lines.append(",".join(cells.values()))
    return "\n".join(lines) + "\n"


def test_500_rows_5_bad_each_reported_with_its_line(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """import-tags names exactly the 5 bad rows (line = data row + 1: the header is line
    1), writes the other 495 as loops of the base config, and that config loads."""
    write(tmp_path, "tags.csv", tag_list_500())
    write(tmp_path, "base.yaml", BASE)
    res = subprocess.run([*CLI, "import-tags", "tags.csv", "--config", "base.yaml", "-o",
                          "gw.yaml"], capture_output=True, text=True, timeout=60, check=False,
                         cwd=tmp_path)
    assert res.returncode == 2, res.stderr
    problems = res.stderr.splitlines()
    lines = sorted(row + 1 for row in BAD)
    assert problems == [
        "tags.csv: line 38: loop FIC0037: column 'type': must be one of int16, uint16, int32, "
        "uint32, float32, float64, was 'flaot32'",
        "tags.csv: line 121: loop FIC0120: column 'device': unknown device 'plc7' (devices: "
        "plc1, plc2, dcs1)",
        "tags.csv: line 251: loop FIC0250: column 'op': must be an integer, was '40x'",
        "tags.csv: line 334: loop FIC0002: column 'name': duplicate loop name 'FIC0002'",
        "tags.csv: line 500: loop FIC0499: column 'window_s': must hold at least 16 samples "
        "of device plc1 (poll_interval_s 1)",
        f"tags.csv: wrote gw.yaml: 495 loop(s); 5 bad row(s) left out (lines "
        f"{', '.join(map(str, lines))})"]
    c = load_config(tmp_path / "gw.yaml")
    assert len(c.loops) == 495
    assert {f"FIC{k:04d}" for k in range(1, 501)} - {lp.name for lp in c.loops} == {
        "FIC0037", "FIC0120", "FIC0250", "FIC0333", "FIC0499"}
    assert len(c.devices) == 3 and c.devices[1].options.unit_id == 3  # the base kept

    # the same list as the config's loops_csv: the same 5 problems, and nothing loads
    write(tmp_path, "direct.yaml", BASE + "loops_csv: tags.csv\n")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as err:
        load_config("direct.yaml")
    assert err.value.problems == problems[:-1]


@pytest.mark.timing
def test_check_config_on_the_imported_500_row_list_is_fast(tmp_path: Path) -> None:
    write(tmp_path, "tags.csv", tag_list_500())
    write(tmp_path, "base.yaml", BASE)
    result = import_tags(tmp_path / "tags.csv", tmp_path / "base.yaml")
    assert result.text is not None and result.loops == 495
    out = write(tmp_path, "gw.yaml", result.text)
    t0 = time.perf_counter()
    res = subprocess.run([*CLI, "check-config", str(out)], capture_output=True, text=True,
                         timeout=60, check=False)
    elapsed = time.perf_counter() - t0
    print(f"check-config on 495 loops: {elapsed:.2f} s (process start included)")
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(f"{out}: ok (3 device(s), 495 loop(s))")
    assert "FIC0001 .. FIC0500 (495 loops, in config order): unit id 1, result_address 0, " \
        "20, .. 9880" in res.stdout
    assert elapsed < 2.0


def test_import_without_a_config_writes_the_loops(tmp_path: Path) -> None:
    """Without --config the devices are taken from the rows (OPC UA where a cell is a node
    id): what a row says of itself is checked, the loops alone are written."""
    csv = write(tmp_path, "tags.csv",
                "name,device,op,pv,type,kp\n"
                "FIC101,plc1,0,2,float32,1.5\n"
                "FIC102,plc1,4,6,float33,\n"
                "TIC201,dcs1,ns=2;s=TIC201.OP,ns=2;s=TIC201.PV,,\n")
    result = import_tags(csv)
    assert result.problems == [
        f"{csv}: line 3: loop FIC102: column 'type': must be one of int16, uint16, int32, "
        "uint32, float32, float64, was 'float33'"]
    assert result.bad_lines == [3]
    assert result.text == (
        "loops:\n"
        "- {name: FIC101, device: plc1, op: {address: 0, type: float32}, pv: {address: 2, "
        "type: float32}, kp: 1.5}\n"
        "- {name: TIC201, device: dcs1, op: {node: ns=2;s=TIC201.OP}, pv: {node: "
        "ns=2;s=TIC201.PV}}\n")


def test_a_bad_base_config_writes_nothing(tmp_path: Path) -> None:
    csv = write(tmp_path, "tags.csv", "name,device,op,pv,type\nA,plc1,0,2,float32\n")
    base = write(tmp_path, "base.yaml", "devices: [{name: plc1, protocol: modbus}]\n")
    result = import_tags(csv, base)
    assert result.text is None
    assert result.problems == [f"{base}: device plc1: missing required key 'host'"]


def test_a_row_with_a_cell_too_few_or_too_many_is_refused_as_such(tmp_path: Path) -> None:
    """Issue 23 item 6: a row whose cells do not match the header is named by its count,
    not by the symptoms of cells read under the wrong columns (a type 'self-regulating', a
    process 1.0), and none of its cells is taken (delay_s no longer falls back silently)."""
    csv = write(tmp_path, "tags.csv",
                "name,device,op,pv,type,process,kp,delay_s\n"
                "FIC101,plc1,0,2,float32,self-regulating,1.0,4\n"
                "LIC201,plc1,4,6,integrating,0.2,3\n"          # 'type' left out: 7 cells
                "TIC301,plc1,8,10,float32,,1.0,6,\n"           # one cell too many: 9
                "TIC302,plc1,12,14,float32,,1.0,6\n")
    result = import_tags(csv, write(tmp_path, "base.yaml", BASE))
    assert result.problems == [
        f"{csv}: line 3 has 7 cells, the header has 8 (loop LIC201): a cell is missing; make "
        "the row one cell per column (leave a cell empty for a default; a cell holding ',' "
        "must be in quotes)",
        f"{csv}: line 4 has 9 cells, the header has 8 (loop TIC301): there is a cell too "
        "many; make the row one cell per column (leave a cell empty for a default; a cell "
        "holding ',' must be in quotes)"]
    assert result.bad_lines == [3, 4] and result.loops == 2
    with pytest.raises(ConfigError) as err:
        load_config(write(tmp_path, "gw.yaml", BASE + "loops_csv: tags.csv\n"))
    assert err.value.problems == [p.replace(str(csv), str(tmp_path / "tags.csv"))
                                  for p in result.problems]
