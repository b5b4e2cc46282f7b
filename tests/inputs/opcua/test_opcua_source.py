"""OPC UA source against the plc-sim's real asyncua server on 127.0.0.1 (raw values: scaling
and plausibility are core.points' job, reconnecting the poller's)."""

from __future__ import annotations

import asyncio
import functools
import logging
import time
from typing import Any

import numpy as np
import pytest
from _opcua_support import (
    PASSWORD,
    Pki,
    client_security,
    device,
    make_pki,
    run,
    server_security,
)
from asyncua import ua
from asyncua.common.callback import CallbackType

from bench._net import free_port
from gateway.core.points import PointSpec, Quality
from gateway.errors import DeviceError
from gateway.inputs.opcua import OpcUaInput
from gateway.inputs.opcua.config import OpcUaPoint
from plcsim.opcua import NAMESPACE_URI, OpcUaPlcServer
from stiction.models.simulate import LoopBank, LoopParams
from stiction.models.valves import HeValve
from stiction.scenarios import scenario

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(60)]

LOOPS = ["FIC101", "LIC102", "TIC205"]
Server = functools.partial(OpcUaPlcServer, clock=False)  # no 1 s clock task to wait for
SCENARIOS = ["table4-case2", "table5-case1", "healthy"]


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    return make_pki(tmp_path_factory.mktemp("pki"))


@pytest.fixture(autouse=True)
def _quiet_asyncua() -> None:
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    logging.getLogger("asyncuagds").setLevel(logging.CRITICAL)


def loop_bank(names: list[str]) -> LoopBank:
    scs = [scenario(n) for n in names]

    def col(field: str) -> list[Any]:
        return [getattr(s, field) for s in scs]

    params = LoopParams(kc=col("kc"), ti=col("ti"), kp=col("kp"), tau=col("tau"),
                        theta=col("theta"), integrating=col("integrating"), noise_sd=0.05)
    return LoopBank(len(scs), params, HeValve(col("fs"), col("fd"), col("k")), ts=1.0, seed=7)


def points(loops: list[str]) -> list[PointSpec]:
    return [PointSpec(loop, role, OpcUaPoint(f"ns=2;s={loop}.{role.upper()}"))
            for loop in loops for role in ("op", "pv")]


class ReadCounter:
    """Counts Read service calls from clients that touch the plc-sim namespace."""

    def __init__(self, server: OpcUaPlcServer) -> None:
        self.calls = 0
        assert server.server is not None
        server.server.subscribe_server_callback(CallbackType.PreRead, self)

    def __call__(self, event: Any, dispatcher: Any) -> None:
        nodes = event.request_params.NodesToRead
        if event.is_external and any(n.NodeId.NamespaceIndex == 2 for n in nodes):
            self.calls += 1


@pytest.mark.parametrize(("policy", "mode"), [
    ("Basic256Sha256", "SignAndEncrypt"),
    ("Basic256Sha256", "Sign"),
    ("Aes256_Sha256_RsaPss", "SignAndEncrypt"),
])
def test_secure_session_with_login_reads_simulated_loops(pki: Pki, policy: str,
                                                        mode: str) -> None:
    """OP and PV of simulated loops arrive exactly as served, one Read call per poll."""
    port = free_port()

    async def main() -> None:
        bank = loop_bank(SCENARIOS)
        sec = server_security(pki, policy=policy, mode=mode, trusted_clients=True)
        async with Server(LOOPS, port=port, security=sec) as server:
            counter = ReadCounter(server)
            cfg = device(port, client_security(pki, policy=policy, mode=mode))
            async with OpcUaInput(cfg, points(LOOPS)) as inp:
                for k in range(30):
                    out = bank.step(52.0 if k >= 5 else 50.0)
                    await server.update(out.op, out.pv)
                    before = counter.calls
                    res = await inp.read()
                    assert counter.calls - before == 1
                    assert res.requests == 1
                    np.testing.assert_array_equal(res.quality, Quality.GOOD)
                    np.testing.assert_array_equal(res.values[0::2], out.op)
                    np.testing.assert_array_equal(res.values[1::2], out.pv)
                    assert res.values.dtype == np.float64
                    assert res.quality.dtype == np.uint8
                    assert abs(res.t - time.time()) < 5

    run(main())


def test_raw_values_nsu_node_ids_and_chunked_reads(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        async with Server(["A", "B"], port=port) as server:
            await server.update([10.0, 20.0], [1.5, 2.5])
            pts = [
                PointSpec("A", "op", "ns=2;s=A.OP", scale=2.0, offset=1.0),
                PointSpec("A", "pv", f"nsu={NAMESPACE_URI};s=A.PV"),
                PointSpec("B", "op", "nsu=urn:no-such-namespace;s=B.OP"),
                PointSpec("B", "pv", OpcUaPoint("ns=2;s=B.PV")),
            ]
            async with OpcUaInput(device(port, max_nodes_per_read=2), pts) as inp:
                res = await inp.read()
            # raw: the point's scale 2 and offset 1 are applied later, by core.points
            np.testing.assert_array_equal(res.values[[0, 1, 3]], [10.0, 1.5, 2.5])
            assert np.isnan(res.values[2])
            assert list(res.quality) == [Quality.GOOD, Quality.GOOD, Quality.BAD, Quality.GOOD]
            assert res.requests == 2  # 3 resolvable nodes, at most 2 per Read

    run(main())


def test_missing_node_is_bad_while_the_others_go_on(pki: Pki,
                                                    caplog: pytest.LogCaptureFixture) -> None:
    port = free_port()

    async def main() -> None:
        sec = server_security(pki)
        async with Server(["A", "B"], port=port, security=sec) as server:
            await server.update([10.0, 20.0], [1.0, 2.0])
            pts = [*points(["A"]), PointSpec("B", "op", "ns=2;s=B.OPX"),
                   PointSpec("B", "pv", "ns=2;s=B.PV")]
            async with OpcUaInput(device(port, client_security(pki)), pts) as inp:
                for _ in range(3):
                    res = await inp.read()
                    assert list(res.quality) == [0, 0, Quality.BAD, 0]
                    np.testing.assert_array_equal(res.values[[0, 1, 3]], [10.0, 1.0, 2.0])
                    assert np.isnan(res.values[2])
                    assert res.requests == 1

    with caplog.at_level(logging.WARNING, logger="gateway.inputs.opcua"):
        run(main())
    # logged once (on the change), naming the loop, the node and the status
    hits = [r.getMessage() for r in caplog.records if "B.OPX" in r.getMessage()]
    assert hits == ["OPC UA device dcs1: loop B op (ns=2;s=B.OPX): BadNodeIdUnknown"]


def test_uncertain_bad_and_non_numeric_values_are_gaps(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        async with Server(["A", "B", "C"], port=port) as server:
            srv = server.server
            assert srv is not None
            await srv.nodes.objects.add_variable(ua.NodeId.from_string("ns=2;s=B.TEXT"),
                                                 "B.TEXT", "broken")
            pts = points(["A", "B", "C"])
            pts[3] = PointSpec("B", "pv", "ns=2;s=B.TEXT")  # a string is no process value
            async with OpcUaInput(device(port), pts) as inp:
                res = await inp.read()  # before the first update: BadWaitingForInitialData
                assert list(res.quality) == [Quality.BAD] * 6
                await server.update([1.0, 2.0, float("nan")], [4.0, 5.0, 6.0])
                await srv.write_attribute_value(
                    ua.NodeId.from_string("ns=2;s=A.PV"),
                    ua.DataValue(ua.Variant(4.0, ua.VariantType.Double),
                                 StatusCode=ua.StatusCode(ua.StatusCodes.UncertainLastUsableValue)))
                res = await inp.read()
            assert list(res.quality) == [Quality.GOOD, Quality.UNCERTAIN, Quality.GOOD,
                                         Quality.BAD, Quality.BAD, Quality.GOOD]
            np.testing.assert_array_equal(res.values[[0, 2, 5]], [1.0, 2.0, 6.0])
            assert np.isnan(res.values[[1, 3, 4]]).all()  # gaps: never 0, never None

    run(main())


def test_wrong_password_is_refused_with_a_clear_auth_error(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        async with Server(["A"], port=port, security=server_security(pki)) as server:
            await server.update([1.0], [2.0])
            cfg = device(port, client_security(pki, password_file=pki.wrong_password_file))
            inp = OpcUaInput(cfg, points(["A"]))
            with pytest.raises(DeviceError, match=r"login refused for user 'gateway' "
                               r"\(BadUserAccessDenied\): check security\.username and "
                               r"security\.password_file") as info:
                await inp.connect()
            assert info.value.kind == "auth"
            assert info.value.device == "dcs1"
            # read() does not log in again by itself: it fails at once, without network
            # traffic; when to try again is the poller's backoff (longer after "auth")
            t0 = time.perf_counter()
            with pytest.raises(DeviceError, match="not connected") as info:
                await inp.read()
            assert info.value.kind == "connect"
            assert time.perf_counter() - t0 < 0.1
            # the same server accepts the right password: the refusal was the password
            async with OpcUaInput(device(port, client_security(pki)), points(["A"])) as ok:
                assert list((await ok.read()).values) == [1.0, 2.0]
            await inp.close()
            assert PASSWORD not in str(info.value)

    run(main())


def test_untrusted_server_certificate_is_refused(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        async with Server(["A"], port=port, security=server_security(pki)):
            cfg = device(port, client_security(pki, trust_store=pki.untrusted))
            with pytest.raises(DeviceError, match=r"server certificate CN=test plc-sim, "
                               r"SHA-1 thumbprint [0-9A-F]{40} is not trusted "
                               r"\(BadCertificateUntrusted\): it is not in the trust store "
                               r".*untrusted; if this is the right server, copy its "
                               r"certificate there") as info:
                await OpcUaInput(cfg, points(["A"])).connect()
            assert info.value.kind == "auth"
            # a pinned server_certificate that is not the server's is refused as well
            cfg = device(port, client_security(pki, server_certificate=pki.other_cert))
            with pytest.raises(DeviceError, match=r"not the one pinned in server_certificate "
                               r"\(CN=other server") as info:
                await OpcUaInput(cfg, points(["A"])).connect()
            assert info.value.kind == "auth"

    run(main())


def test_server_refusing_the_gateway_certificate_or_the_mode(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        sec = server_security(pki, trusted_clients=True)
        sec = type(sec)(**{**sec.__dict__, "trusted_clients": pki.untrusted})
        async with Server(["A"], port=port, security=sec):
            with pytest.raises(DeviceError, match=r"the server refused the secure channel or "
                               r"the gateway's certificate \(BadCertificateUntrusted\): make "
                               r"the server trust the gateway's certificate .*client\.der"):
                await OpcUaInput(device(port, client_security(pki)), points(["A"])).connect()
            cfg = device(port, client_security(pki, mode="Sign"))
            with pytest.raises(DeviceError, match=r"the server offers no Basic256Sha256/Sign "
                               r"endpoint \(it offers: Basic256Sha256/SignAndEncrypt\)"):
                await OpcUaInput(cfg, points(["A"])).connect()

    run(main())


def test_server_down_at_start_then_up(pki: Pki) -> None:
    port = free_port()

    async def main() -> None:
        inp = OpcUaInput(device(port, client_security(pki)), points(["A"]))
        with pytest.raises(DeviceError, match=r"refused the connection") as info:
            await inp.connect()
        assert info.value.kind == "connect"
        async with Server(["A"], port=port, security=server_security(pki)) as server:
            await server.update([3.0], [4.0])
            res = await _read_until_ok(inp, 5.0)
            assert list(res.values) == [3.0, 4.0]
        await inp.close()

    run(main())


async def _read_until_ok(inp: OpcUaInput, limit: float) -> Any:
    """Read as the poller does: after a failure, close and connect again."""
    deadline = time.monotonic() + limit
    while True:
        try:
            if not inp.connected:
                await inp.connect()
            return await inp.read()
        except DeviceError:
            await inp.close()
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.1)


def test_server_restart_mid_run_resumes_without_a_new_adapter(pki: Pki) -> None:
    """During the outage read() raises DeviceError (a gap); after the restart the same
    source connects and reads again, with the new values."""
    port = free_port()

    async def main() -> dict[str, Any]:
        server = Server(["A", "B"], port=port, security=server_security(pki))
        await server.start()
        await server.update([1.0, 2.0], [3.0, 4.0])
        inp = OpcUaInput(device(port, client_security(pki)), points(["A", "B"]))
        await inp.connect()
        assert list((await inp.read()).values) == [1.0, 3.0, 2.0, 4.0]
        await server.stop()
        kinds = []
        t_down = time.monotonic()
        while time.monotonic() - t_down < 2.0:  # polls during the outage
            t0 = time.monotonic()
            with pytest.raises(DeviceError) as info:
                await inp.read()
            assert time.monotonic() - t0 < 1.5  # a poll never hangs on a dead server
            kinds.append(info.value.kind)
            await asyncio.sleep(0.2)
        server2 = Server(["A", "B"], port=port, security=server_security(pki))
        await server2.start()
        await server2.update([5.0, 6.0], [7.0, 8.0])
        t_up = time.monotonic()
        res = await _read_until_ok(inp, 15.0)
        resumed = time.monotonic() - t_up
        assert list(res.values) == [5.0, 7.0, 6.0, 8.0]
        assert list(res.quality) == [Quality.GOOD] * 4
        await inp.close()
        await server2.stop()
        return {"kinds": kinds, "resumed_s": resumed}

    out = run(main(), timeout=45)
    assert out["kinds"]
    assert set(out["kinds"]) <= {"connect", "timeout"}
    assert out["resumed_s"] < 5.0
    print(f"OPC UA restart: {len(out['kinds'])} failed polls, resumed "
          f"{out['resumed_s']:.2f} s after the server came back")


def test_silent_server_times_out_within_the_budget(pki: Pki) -> None:
    """A server that accepts TCP but never answers: DeviceError(timeout), bounded."""

    async def main() -> float:
        async def swallow(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            await reader.read(65536)
            await asyncio.sleep(30)

        tcp = await asyncio.start_server(swallow, "127.0.0.1", 0)
        port = tcp.sockets[0].getsockname()[1]
        async with tcp:
            inp = OpcUaInput(device(port, timeout_s=0.5), points(["A"]))
            t0 = time.monotonic()
            with pytest.raises(DeviceError, match=r"no answer from .* within the timeout "
                               "while connecting") as info:
                await inp.connect()
            assert info.value.kind == "timeout"
            await inp.close()
            return time.monotonic() - t0

    assert run(main()) < 3.0


def test_close_is_idempotent_and_never_raises(pki: Pki) -> None:
    async def main() -> None:
        inp = OpcUaInput(device(free_port()), points(["A"]))
        await inp.close()
        with pytest.raises(DeviceError):
            await inp.connect()
        await inp.close()
        await inp.close()

    run(main())
