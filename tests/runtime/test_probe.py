"""``stiction-gateway probe`` and ``browse`` (issue 16) against the simulated PLC: the values
the PLC holds, decoded and scaled as the gateway would; errors that name the device and the
address (an exception code, a timeout, BadNodeIdUnknown); a stopped PLC exits non-zero
naming the device; ``browse`` lists the simulated PLC's nodes."""

from __future__ import annotations

import asyncio
import logging
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from gateway_helpers import run, sim_config
from reliability_helpers import SilentServer

from bench._net import free_port
from gateway.config import load_config
from gateway.core.points import Quality
from gateway.inputs.opcua.browse import browse
from gateway.inputs.opcua.config import OpcUaDeviceConfig
from gateway.runtime.probe import format_probe, probe
from plcsim import PlcSim, gateway_config

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]
CLI = [sys.executable, "-m", "gateway.cli"]
LOOPS = [{"name": "FIC101", "scenario": "table4-case2"},
         {"name": "LIC201", "scenario": "table5-case2"},
         {"name": "TIC301", "scenario": "healthy"}]


@pytest.fixture(autouse=True)
def _quiet_asyncua() -> None:
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)


def slow_sim(protocol: str = "modbus") -> Any:
    """A simulated PLC that steps once (at start) and then not for 1000 s: its values hold
    still while they are compared."""
    return sim_config(LOOPS, ts=1.0, time_scale=0.001, protocol=protocol)


def write_config(tmp: Path, sim: Any, port: int, edit: Any = None, *,
                 positions: bool = False) -> Path:
    """The plc-sim's gateway config; without ``positions`` its loops' position points
    are left out (the tests of OP and PV's decoding)."""
    raw = gateway_config(sim, port=port, metrics_listen="127.0.0.1:0",
                         result_listen="127.0.0.1:0")
    if not positions:
        for lp in raw["loops"]:
            lp.pop("position", None)
    if edit is not None:
        edit(raw)
    path = tmp / "gw.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


async def cli(*args: str) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(*CLI, *args, stdout=asyncio.subprocess.PIPE,
                                                stderr=asyncio.subprocess.PIPE)
    out, err = await proc.communicate()
    assert proc.returncode is not None
    return proc.returncode, out.decode(), err.decode()


def table(text: str) -> dict[tuple[str, str], list[str]]:
    """(loop, point) -> the cells of a probe table's row (columns start where the header's
    names do: an address may hold spaces)."""
    head, *lines = text.splitlines()
    starts = [i for i, ch in enumerate(head) if ch != " " and (i == 0 or head[i - 1] == " ")]
    rows = [[line[a:b].strip() for a, b in zip(starts, [*starts[1:], None], strict=True)]
            for line in lines]
    return {(r[0], r[1]): r for r in rows}


def test_probe_prints_what_the_plc_holds_decoded_and_scaled(tmp_path: Path) -> None:
    sim = slow_sim()

    def edit(raw: dict[str, Any]) -> None:
        raw["loops"][1]["pv"].update(scale=0.1, offset=-50.0)  # LIC201's PV scaled
        raw["loops"][2]["pv"]["range"] = [1000, 2000]  # TIC301's PV implausible: BAD

    async def go() -> None:
        async with PlcSim(sim) as plc:
            path = write_config(tmp_path, sim, plc.port, edit, positions=True)
            results = await probe(load_config(path))
            (dev,) = results
            assert dev.device == "plc-sim" and dev.error is None and not dev.ok
            rows = {(r.loop, r.role): r for r in dev.rows}
            for i, name in enumerate(["FIC101", "LIC201", "TIC301"]):  # the valves' own
                assert rows[name, "position"].value == np.float32(plc.position[i])
            for i, name in enumerate(["FIC101", "LIC201", "TIC301"]):
                op, pv = np.float32(plc.op[i]), np.float32(plc.pv[i])  # float32 registers
                assert rows[name, "op"].raw == op and rows[name, "op"].value == op
                assert rows[name, "pv"].raw == pv
                assert rows[name, "op"].address == f"holding {4 * i} float32"
            assert rows["LIC201", "pv"].value == pytest.approx(float(pv_of(plc, 1)) * 0.1 - 50)
            assert rows["FIC101", "pv"].value == float(np.float32(plc.pv[0]))
            assert rows["TIC301", "pv"].quality == Quality.BAD
            assert np.isnan(rows["TIC301", "pv"].value)
            assert "IMPLAUSIBLE  50 is outside its range 1000..2000" in format_probe(results)
            # the command prints the same, 7 significant digits
            code, out, err = await cli("probe", "--config", str(path), "FIC101", "LIC201")
            assert code == 0, err
            got = table(out)
            assert set(got) == {(n, p) for n in ("FIC101", "LIC201")
                                for p in ("op", "pv", "position")}
            assert float(got["FIC101", "op"][5]) == pytest.approx(plc.op[0], rel=1e-6)
            assert float(got["FIC101", "pv"][5]) == pytest.approx(plc.pv[0], rel=1e-6)
            assert float(got["LIC201", "pv"][5]) == pytest.approx(plc.pv[1] * 0.1 - 50,
                                                                  rel=1e-6)
            assert got["LIC201", "pv"][6] == "GOOD"
            assert err.splitlines()[-1] == "6 of 6 point(s) good"
            code, _, err = await cli("probe", "--config", str(path))
            assert code == 1, err  # TIC301's PV is BAD
            code, _, err = await cli("probe", "--config", str(path), "FIC999")
            assert code == 2 and err == f"{path}: no loop 'FIC999'\n"

    run(go(), 90)


def pv_of(plc: PlcSim, i: int) -> np.float32:
    return np.float32(plc.pv[i])


def test_probe_names_the_request_of_an_exception_code(tmp_path: Path) -> None:
    sim = slow_sim()

    def edit(raw: dict[str, Any]) -> None:
        raw["loops"][2]["op"]["address"] = 400  # past the simulated PLC's registers
        raw["loops"][2]["pv"]["address"] = 402

    async def go() -> None:
        async with PlcSim(sim) as plc:
            path = write_config(tmp_path, sim, plc.port, edit)
            code, out, err = await cli("probe", "--config", str(path))
            assert code == 1
            got = table(out)
            assert got["FIC101", "op"][6] == "GOOD"
            words = ("holding 400+4: illegal data address (exception 2): registers 400..403 "
                     "are outside the PLC's map (some or all); check the address of TIC301 op "
                     "and pv against the PLC's register list; addresses are 0-based: 40001 "
                     "is 0")
            assert got["TIC301", "op"][3:7] == ["holding 400 float32", "nan", "nan", "NO_COMM"]
            assert got["TIC301", "op"][7] == words
            assert f"stiction-gateway: device plc-sim: {words}" in err
            assert err.splitlines()[-1] == "4 of 6 point(s) good"

    run(go(), 60)


def test_probe_of_a_stopped_plc_exits_non_zero_naming_the_device(tmp_path: Path) -> None:
    port = free_port()
    path = write_config(tmp_path, slow_sim(), port)
    code, out, err = run(cli("probe", "--config", str(path)), 60)
    assert code == 1
    assert out == ""
    assert err.splitlines() == [
        f"stiction-gateway: device plc-sim: cannot connect to 127.0.0.1:{port}",
        "0 of 6 point(s) good"]


def test_probe_timeout_names_the_request(tmp_path: Path) -> None:
    async def go() -> None:
        async with SilentServer() as silent:
            path = write_config(tmp_path, slow_sim(), silent.port,
                                lambda raw: raw["devices"][0].update(timeout_s=0.2))
            code, _, err = await cli("probe", "--config", str(path), "LIC201")
            assert code == 1
            assert err.splitlines()[0].startswith(
                "stiction-gateway: device plc-sim: holding 4+4 (unit id 1): no answer within "
                "0.2 s")

    run(go(), 60)


def test_probe_and_browse_over_opcua(tmp_path: Path) -> None:
    sim = slow_sim("opcua")

    def edit(raw: dict[str, Any]) -> None:
        raw["loops"][2]["pv"]["node"] = "ns=2;s=TIC301.PVX"  # a node the server lacks

    async def go() -> None:
        async with PlcSim(sim) as plc:
            path = write_config(tmp_path, sim, plc.port, edit)
            (dev,) = await probe(load_config(path))
            rows = {(r.loop, r.role): r for r in dev.rows}
            assert rows["FIC101", "op"].value == plc.op[0]
            assert rows["LIC201", "pv"].value == plc.pv[1]
            assert rows["LIC201", "pv"].address == "ns=2;s=LIC201.PV"
            bad = rows["TIC301", "pv"]
            assert (bad.quality, bad.status) == (Quality.BAD, "BadNodeIdUnknown")
            assert not dev.ok

            endpoint = f"opc.tcp://127.0.0.1:{plc.port}"
            found = await browse(OpcUaDeviceConfig("", endpoint, 1.0, 1.0))
            assert [(v.node, v.data_type, v.path) for v in found] == [
                (f"ns=2;s={n}.{p}", "Double", f"{n}/{n}.{p}")
                for n in ("FIC101", "LIC201", "TIC301") for p in ("OP", "PV", "POS")]
            assert float(found[0].value) == pytest.approx(plc.op[0], rel=1e-6)

            code, out, err = await cli("browse", endpoint, "ns=2;s=LIC201")
            assert code == 0, err
            assert [line.split()[0] for line in out.splitlines()] == [
                "node", "ns=2;s=LIC201.OP", "ns=2;s=LIC201.PV", "ns=2;s=LIC201.POS"]
            code, out, err = await cli("browse", "plc-sim", "--config", str(path))
            assert code == 0, err
            assert "ns=2;s=TIC301.PV" in out
            code, out, err = await cli("browse", endpoint, "ns=2;s=NOPE")
            assert code == 1
            assert err == (f"stiction-gateway: device {endpoint}: browsing node ns=2;s=NOPE: "
                           "BadNodeIdUnknown\n")
            port = plc.port
        code, _, err = await cli("browse", f"opc.tcp://127.0.0.1:{port}")
        assert code == 1
        assert "refused the connection" in err and f"127.0.0.1:{port}" in err

    run(go(), 90)
