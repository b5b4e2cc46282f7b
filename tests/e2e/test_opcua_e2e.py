"""End to end over OPC UA: plc-sim (Basic256Sha256 SignAndEncrypt, user login, trusted
client list) -> gateway (config loaded through the protocol plugin) -> result store."""

from __future__ import annotations

import asyncio
import logging
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from _opcua_support import PASSWORD, USER, Pki, make_pki, run

from gateway.config import load_config
from gateway.core.points import Quality
from gateway.errors import ConfigError
from gateway.runtime.gateway import Gateway
from plcsim import PlcSim, gateway_config, load_sim_config
from stiction.diagnosis.travel import MEASURED

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(90)]
FAKE = "opcua_fake_analyze:analyze"
SLIP = 1.99 * (0.30 - 0.27)  # He's slip J = K (fs - fd) of table4-case2's valve


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    logging.getLogger("asyncuagds").setLevel(logging.CRITICAL)
    return make_pki(tmp_path_factory.mktemp("pki"))


def write_configs(pki: Pki, tmp: Path, *, password: str = PASSWORD) -> tuple[Path, Path]:
    (tmp / "secrets").mkdir(exist_ok=True)
    (tmp / "secrets" / "sim.pw").write_text(PASSWORD + "\n")
    (tmp / "secrets" / "gw.pw").write_text(password + "\n")
    sim = {
        "listen": "127.0.0.1:0", "ts": 1.0, "time_scale": 50.0, "protocol": "opcua",
        "opcua": {"certificate": str(pki.server_cert), "private_key": str(pki.server_key),
                  "policy": "Basic256Sha256", "mode": "SignAndEncrypt", "username": USER,
                  "password_file": "secrets/sim.pw",
                  "trusted_clients": str(pki.trusted_clients)},
        "loops": [{"name": "FIC101", "scenario": "table4-case2", "noise": 0.02,
                   "window_s": 3000},
                  {"name": "TIC301", "scenario": "healthy", "noise": 0.02, "window_s": 3000}],
    }
    sim_path = tmp / "plc-sim.yaml"
    sim_path.write_text(yaml.safe_dump(sim))
    return sim_path, tmp / "gateway.yaml"


def gateway_yaml(sim_path: Path, gw_path: Path, port: int, pki: Pki) -> None:
    raw = gateway_config(load_sim_config(sim_path), port=port, analysis_interval_s=60.0,
                         metrics_listen="127.0.0.1:0", result_listen="127.0.0.1:0",
                         opcua_security={
                             "policy": "Basic256Sha256", "mode": "SignAndEncrypt",
                             "certificate": str(pki.client_cert),
                             "private_key": str(pki.client_key),
                             "trust_store": str(pki.trusted), "username": USER,
                             "password_file": "secrets/gw.pw"})
    gw_path.write_text(yaml.safe_dump(raw))


def test_plcsim_to_gateway_over_secure_opcua(pki: Pki, tmp_path: Path) -> None:
    """As the Modbus end-to-end test, over OPC UA: the real stiction.analyze in worker
    processes calls the sticky loop `stiction` with fd and fs within 10 % of the simulated
    valve's (0.27, 0.30), measured from the valve's position read as a third node, and the
    healthy loop not called sticky."""
    sim_path, gw_path = write_configs(pki, tmp_path)

    async def main() -> None:
        async with PlcSim(load_sim_config(sim_path)) as sim:
            assert sim.opcua is not None
            gateway_yaml(sim_path, gw_path, sim.port, pki)
            cfg = load_config(gw_path)  # through the opcua protocol plugin
            assert cfg.devices[0].protocol == "opcua"
            gw = Gateway(cfg, serve_http=False)
            gw.align_polls(sim.mid_step())
            async with gw:
                deadline = time.monotonic() + 60
                while time.monotonic() < deadline:
                    names = [gw.store.verdict_name(i) for i in range(2)]
                    first = gw.store.results[0]
                    sized = first is not None and first.assessment.fd is not None
                    if names[0] == "stiction" and sized and gw.store.results[1] is not None:
                        break
                    await asyncio.sleep(0.5)
                assert names[0] == "stiction", gw.store.results[0]
                # the healthy valve is never called sticky; on a loaded box (ticks missed at
                # 50x, a session re-established) its window has gaps and the analysis may
                # not decide, which it says: `undetermined` (once in CI, held after a
                # reconnect), never a call a crew would act on
                assert names[1] in {"not_oscillating", "warming_up", "bad_data",
                                    "undetermined"}, gw.store.results[1]
                sticky = gw.store.results[0]
                assert sticky is not None
                a = sticky.assessment
                assert a.fd == pytest.approx(0.27, rel=0.10)
                assert a.fs == pytest.approx(0.30, rel=0.10)
                # issue 30: the valve's position read over OPC UA (plc-sim's FIC101.POS), the
                # loop decided from its travel: band 2 fs - J and slip J = K (fs - fd) of He's
                # valve (fs 0.30, fd 0.27, K 1.99) within 10 %
                assert cfg.loops[0].position is not None
                assert "FIC101.POS" in str(cfg.loops[0].position.address)
                assert MEASURED in a.reason
                assert a.jump == pytest.approx(SLIP, rel=0.10)
                assert a.band == pytest.approx(2 * 0.30 - SLIP, rel=0.10)
                # the latest samples are the simulated ones (float64 over OPC UA)
                assert np.all(np.isfinite(gw.store.latest_op))
                assert np.all(np.abs(gw.store.latest_pv - 50.0) < 10.0)
                poller = gw.pollers[0]
                assert poller.up is True

    run(main(), timeout=85)


def test_gateway_config_errors_name_the_opcua_keys(pki: Pki, tmp_path: Path) -> None:
    sim_path, gw_path = write_configs(pki, tmp_path)
    gateway_yaml(sim_path, gw_path, 4840, pki)
    raw = yaml.safe_load(gw_path.read_text())
    raw["devices"][0]["security"]["certificate"] = "pki/missing.der"
    raw["devices"][0]["security"]["mdoe"] = "Sign"
    raw["loops"][0]["op"] = {"node": "FIC101.OP"}
    gw_path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError) as info:
        load_config(gw_path)
    src = str(gw_path)
    assert info.value.problems == [
        f"{src}: device plc-sim: unknown key 'security.mdoe' (known: policy, mode, "
        "certificate, private_key, server_certificate, trust_store, username, password_file)",
        f"{src}: device plc-sim: key 'security.certificate': file not found: pki/missing.der "
        f"({tmp_path / 'pki/missing.der'})",
        f"{src}: loop FIC101: key 'op.node': is not an OPC UA node id (e.g. 'ns=2;s=TIC205.OP', "
        "'ns=3;i=1001', 'nsu=urn:plant;s=TIC205.OP'), was 'FIC101.OP'",
    ]


def test_wrong_password_device_down_rest_of_gateway_works(pki: Pki, tmp_path: Path) -> None:
    sim_path, gw_path = write_configs(pki, tmp_path, password="wrong")

    async def main() -> None:
        async with PlcSim(load_sim_config(sim_path)) as sim:
            gateway_yaml(sim_path, gw_path, sim.port, pki)
            cfg = load_config(gw_path)
            async with Gateway(cfg, analyze=FAKE, serve_http=False) as gw:
                await asyncio.sleep(2.0)
                assert gw.pollers[0].up is False
                assert gw.result_port > 0  # the result server still serves

    run(main(), timeout=60)


@pytest.mark.timing  # the reconnect gaps are counted in 20 ms ticks
def test_opcua_server_restart_mid_run_is_a_gap_then_polling_resumes(pki: Pki,
                                                                    tmp_path: Path) -> None:
    """The plc-sim's OPC UA server restarts; the gateway keeps running, the outage is
    a gap (NO_COMM, NaN) in the window, and good samples follow it."""
    sim_path, gw_path = write_configs(pki, tmp_path)

    async def main() -> tuple[list[int], int]:
        async with PlcSim(load_sim_config(sim_path)) as sim:
            assert sim.opcua is not None
            gateway_yaml(sim_path, gw_path, sim.port, pki)
            async with Gateway(load_config(gw_path), analyze=FAKE, serve_http=False) as gw:
                bank = gw.pollers[0].groups[0].bank
                await asyncio.sleep(1.5)
                await sim.opcua.stop()
                await asyncio.sleep(1.5)  # 1.5 s at 50x: ~75 process-second polls
                await sim.opcua.start()
                deadline = time.monotonic() + 15
                while time.monotonic() < deadline:
                    await asyncio.sleep(0.5)
                    _, _, q = bank.latest()
                    if np.all(q == Quality.GOOD):
                        break
                await asyncio.sleep(1.0)
                _, op, _, quality = bank.series([0])
                qs = [int(x) for x in quality[0]]
                gap = [k for k, x in enumerate(qs) if x == Quality.NO_COMM]
                assert all(np.isnan(op[0][gap]))
                return qs, len(gap)

    qs, n_gap = run(main(), timeout=80)
    runs: list[tuple[int, int]] = []  # (quality, length) run-length encoding of the window
    for q in qs:
        if runs and runs[-1][0] == q:
            runs[-1] = (q, runs[-1][1] + 1)
        else:
            runs.append((q, 1))
    assert {q for q, _ in runs} <= {Quality.GOOD, Quality.NO_COMM}
    # the outage (1.5 s stopped + restart, at 50x: well over 50 ticks) is one long gap ...
    outage = max(range(len(runs)), key=lambda i: runs[i][1] if runs[i][0] else -1)
    assert runs[outage][0] == Quality.NO_COMM and runs[outage][1] >= 50
    # ... with good samples before it and after it: the same gateway resumed polling
    assert sum(n for q, n in runs[:outage] if q == Quality.GOOD) >= 40
    assert runs[-1][0] == Quality.GOOD and runs[-1][1] >= 30
    # the only other gaps are the few ticks a (re)connect takes (secure channel + session)
    assert all(n <= 10 for i, (q, n) in enumerate(runs) if q and i != outage)
    print(f"OPC UA restart under the gateway: {n_gap} gap samples, outage gap "
          f"{runs[outage][1]}, {runs[-1][1]} good samples after it")
