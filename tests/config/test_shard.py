"""`stiction-gateway shard` (docs/fleet.md): a tag list split over N gateways by PLC, so no
PLC is polled by two gateways, each gateway's result blocks as that gateway assigns them."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
import yaml

from gateway.cli import main
from gateway.config import Config, load_config, parse_config
from gateway.config.shard import plc_key, shard_tags
from gateway.errors import ConfigError

BASE = """\
gateway: {site: plant-north, area: crude}
metrics: {listen: 0.0.0.0:9108}
devices:
  - {name: plc1, protocol: modbus, host: 10.0.0.1}
  - {name: plc1b, protocol: modbus, host: 10.0.0.1, unit_id: 2}   # same PLC, another unit id
  - {name: plc2, protocol: modbus, host: 10.0.0.2}
  - {name: plc3, protocol: modbus, host: 10.0.0.3, port: 5020}
  - {name: opc1, protocol: opcua, endpoint: "opc.tcp://10.0.0.4:4840"}
  - {name: opc1b, protocol: opcua, endpoint: "opc.tcp://10.0.0.4:4840/other"}
  - {name: spare, protocol: modbus, host: 10.0.0.9}
loops:
  - {name: OWN1, device: plc2, op: {address: 900, type: float32}, pv: {address: 902, type: float32}}
"""


def _tag_list(path: Path, counts: dict[str, int], pinned: str | None = None) -> list[str]:
    """A tag list with ``counts`` loops per device, the devices' rows interleaved."""
    rows, names = [], []
    left = dict(counts)
    k = 0
    while any(left.values()):
        for dev, count in counts.items():
            if not left[dev]:
                continue
            j = count - left[dev]
            left[dev] -= 1
            name = f"L{k:03d}"
            names.append(name)
            if dev.startswith("opc"):
                op, pv = f"ns=2;s={name}.OP", f"ns=2;s={name}.PV"
            else:
                op, pv = str(4 * j), str(4 * j + 2)
            address = "500" if name == pinned else ""
            rows.append(f'{name};{dev};"{op}";"{pv}";{"" if dev.startswith("opc") else "float32"};'
                        f"{address}")
            k += 1
    path.write_text("# exported from the DCS\nName;Device;OP;PV;Type;Result_Address\n"
                    + "\n".join(rows) + "\n", encoding="utf-8")
    return names


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path, list[str]]:
    (tmp_path / "base.yaml").write_text(BASE)
    counts = {"plc1": 5, "plc1b": 3, "plc2": 6, "plc3": 2, "opc1": 1, "opc1b": 2}
    names = _tag_list(tmp_path / "loops.csv", counts, pinned="L004")
    return tmp_path / "base.yaml", tmp_path / "loops.csv", names


def test_plcs_go_whole_to_the_least_loaded_gateway(files: tuple[Path, Path, list[str]]
                                                   ) -> None:
    base, tags, names = files
    shards, idle = shard_tags(tags, 3, base)
    assert idle == ["spare"]
    by = {s.number: s for s in shards}
    # PLCs: 10.0.0.1:502 (plc1 + plc1b: 8 loops), 10.0.0.2:502 (plc2: 6 + OWN1 = 7),
    # 10.0.0.4:4840 (opc1 + opc1b: 3), 10.0.0.3:5020 (plc3: 2); dealt largest first
    assert by[1].plcs == ("10.0.0.1:502",) and by[1].devices == ("plc1", "plc1b")
    assert by[2].plcs == ("10.0.0.2:502",) and by[2].devices == ("plc2",)
    assert by[3].plcs == ("10.0.0.3:5020", "10.0.0.4:4840")
    assert by[3].devices == ("plc3", "opc1", "opc1b")
    assert [s.loops for s in shards] == [8, 7, 5]
    # every loop exactly once, each shard's in the order of the tag list (base loops first)
    got = [lp.name for s in shards for lp in s.config.loops]
    assert sorted(got) == sorted([*names, "OWN1"])
    for s in shards:
        listed = [lp.name for lp in s.config.loops if lp.name != "OWN1"]
        assert listed == [n for n in names if n in set(listed)]
    assert by[2].config.loops[0].name == "OWN1"
    # the rest of the base config is every gateway's
    for s in shards:
        assert (s.config.gateway.site, s.config.gateway.area) == ("plant-north", "crude")
        assert s.config.metrics.listen == ("0.0.0.0", 9108)


def test_result_blocks_are_those_each_gateway_assigns(files: tuple[Path, Path, list[str]],
                                                      tmp_path: Path) -> None:
    base, tags, _ = files
    out = tmp_path / "out"
    assert main(["shard", "--gateways", "3", "--config", str(base), str(tags),
                 "-o", str(out), "--name", "north"]) == 0
    shards, _ = shard_tags(tags, 3, base, name="north")
    for s in shards:
        loaded = load_config(out / s.yaml_name)  # what the gateway will load
        assert [(lp.name, lp.device, lp.result_unit_id, lp.result_address)
                for lp in loaded.loops] == [
            (lp.name, lp.device, lp.result_unit_id, lp.result_address) for lp in s.config.loops]
        addresses = {lp.name: lp.result_address for lp in loaded.loops}
        if "L004" in addresses:  # the pinned one keeps its cell
            assert addresses["L004"] == 500
        free = sorted(a for n, a in addresses.items() if n != "L004")
        assert free == list(range(0, 20 * len(free), 20))  # from 0, as this gateway numbers
        text = (out / s.yaml_name).read_text()
        assert yaml.safe_load(text)["loops_csv"] == s.csv_name
        csv_lines = (out / s.csv_name).read_text().splitlines()
        assert csv_lines[1] == "name,device,op,pv,type,result_address"


def test_the_cli_says_what_went_where(files: tuple[Path, Path, list[str]], tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    base, tags, _ = files
    assert main(["shard", "--gateways", "2", "--config", str(base), str(tags),
                 "-o", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"{tags}: 20 loop(s) on 4 PLC(s) over 2 gateway(s):"
    assert out[1] == "  left out, no loop reads them: spare"
    assert out[2].startswith("  gateway-1.yaml (gateway-1.csv): 10 loop(s), devices plc1, "
                             "plc1b, plc3 (PLC 10.0.0.1:502, 10.0.0.3:5020); unit id 1 "
                             "result_address 0..")
    assert out[3].startswith("  gateway-2.yaml (gateway-2.csv): 10 loop(s), devices plc2, "
                             "opc1, opc1b")
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [
        "gateway-1.csv", "gateway-1.yaml", "gateway-2.csv", "gateway-2.yaml"]


def test_a_bad_row_or_too_many_gateways_writes_nothing(
        files: tuple[Path, Path, list[str]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    base, tags, _ = files
    out = tmp_path / "none"
    assert main(["shard", "--gateways", "5", "--config", str(base), str(tags),
                 "-o", str(out)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"{tags}: cannot split over 5 gateway(s): its loops are on 4 PLC(s) (10.0.0.1:502, "
        "10.0.0.2:502, 10.0.0.3:5020, 10.0.0.4:4840), and a PLC is polled by one gateway")
    tags.write_text(tags.read_text().replace("L000;plc1;", "L000;plc7;"))
    assert main(["shard", "--gateways", "2", "--config", str(base), str(tags),
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "line 3: loop L000: column 'device': unknown device 'plc7'" in err
    assert not out.exists()


def test_without_a_config_each_device_is_a_plc(tmp_path: Path) -> None:
    tags = tmp_path / "t.csv"
    names = _tag_list(tags, {"plcA": 4, "plcB": 4, "plcC": 1})
    shards, idle = shard_tags(tags, 2)
    assert idle == []
    assert [s.devices for s in shards] == [("plcA", "plcC"), ("plcB",)]
    assert sorted(lp.name for s in shards for lp in s.config.loops) == sorted(names)
    assert "host: localhost" in shards[0].yaml_text  # a placeholder, as import-tags writes


def test_plc_key_is_the_endpoint() -> None:
    cfg = load_config_text(BASE + "  - {name: X, device: plc3, op: {address: 0, type: "
                           "float32}, pv: {address: 2, type: float32}}\n")
    keys = {d.name: plc_key(d) for d in cfg.devices}
    assert keys == {"plc1": "10.0.0.1:502", "plc1b": "10.0.0.1:502", "plc2": "10.0.0.2:502",
                    "plc3": "10.0.0.3:5020", "opc1": "10.0.0.4:4840",
                    "opc1b": "10.0.0.4:4840", "spare": "10.0.0.9:502"}


def load_config_text(text: str) -> Config:
    return parse_config(yaml.safe_load(text), "base.yaml")


@pytest.mark.parametrize("seed", range(20))
def test_random_lists_split_whole_and_balanced(tmp_path: Path, seed: int) -> None:
    """Any list, any N up to the PLCs: each loop once, each PLC on one gateway, and the
    gateways' loop counts differ by at most the largest PLC's (largest-first dealing)."""
    rnd = random.Random(seed)
    plcs = rnd.randint(1, 12)
    devices = "\n".join(f"  - {{name: d{i}, protocol: modbus, host: 10.1.0.{i % plcs}, "
                        f"unit_id: {1 + i // plcs}}}" for i in range(2 * plcs))
    (tmp_path / "b.yaml").write_text(f"devices:\n{devices}\n")
    counts = {f"d{i}": rnd.randint(1, 30) for i in range(2 * plcs)}
    names = _tag_list(tmp_path / "t.csv", counts)
    n = rnd.randint(1, plcs)
    shards, _ = shard_tags(tmp_path / "t.csv", n, tmp_path / "b.yaml")
    assert len(shards) == n
    assert sorted(lp.name for s in shards for lp in s.config.loops) == sorted(names)
    owner = {p: s.number for s in shards for p in s.plcs}
    assert len(owner) == sum(len(s.plcs) for s in shards) == plcs
    loads: dict[str, int] = {}
    for d, c in counts.items():
        host = f"10.1.0.{int(d[1:]) % plcs}:502"
        loads[host] = loads.get(host, 0) + c
    assert set(loads) == set(owner)
    sizes = [s.loops for s in shards]
    assert max(sizes) - min(sizes) <= max(loads.values())
    with pytest.raises(ConfigError):
        shard_tags(tmp_path / "t.csv", plcs + 1, tmp_path / "b.yaml")


def test_a_list_too_large_for_one_gateway_is_split(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """The point of sharding: 4,000 loops do not fit one result unit id (3,276 blocks), but
    two gateways of 2,000 each do; the whole list is not refused for what only a single
    gateway would hold. One PLC too large for any gateway is refused, nothing written."""
    tags = tmp_path / "big.csv"
    names = _tag_list(tags, {"plcA": 2000, "plcB": 2000})
    head, *rows = tags.read_text().splitlines(keepends=True)[1:]
    rows.sort(key=lambda row: row.split(";")[1])  # all of plcA, then all of plcB
    tags.write_text(head + "".join(rows))
    shards, _ = shard_tags(tags, 2)
    assert [s.loops for s in shards] == [2000, 2000]
    assert sorted(lp.name for s in shards for lp in s.config.loops) == sorted(names)
    for s in shards:
        assert max(lp.result_address for lp in s.config.loops) == 20 * 1999
    tags = tmp_path / "huge.csv"
    _tag_list(tags, {"plcA": 3300, "plcB": 10})
    out = tmp_path / "none"
    assert main(["shard", "--gateways", "2", str(tags), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no free result block left on result unit id 1" in err
    assert not out.exists()
