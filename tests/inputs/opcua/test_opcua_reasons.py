"""Issue 31, finding 3, the rules in memory: each OPC UA refusal has its own few words in
``stiction_device_down_reason`` (main: "login refused" for every certificate failure), and
a read whose every node the server refuses is one device error (main: none; the device
stayed up). Against the simulated PLC's server: tests/e2e/test_opcua_refusals.py."""

from __future__ import annotations

import datetime
from pathlib import Path

import numpy as np
import pytest
from _opcua_support import expired_copy, make_pki
from asyncua import ua
from asyncua.ua.status_codes import StatusCodes
from asyncua.ua.uaerrors import UaStatusCodeError

from gateway.core.points import PointSpec
from gateway.inputs.opcua.config import OpcUaSecurity
from gateway.inputs.opcua.errors import map_error
from gateway.inputs.opcua.session import server_cert_reason
from gateway.inputs.opcua.values import refused
from gateway.wire.certs import load_certificate_file


def _points(n: int) -> list[PointSpec]:
    return [PointSpec(loop=f"L{k // 2}", role=("op", "pv")[k % 2], address=f"ns=2;s=L{k}")
            for k in range(n)]


def _ids(n: int) -> list[ua.NodeId]:
    return [ua.NodeId.from_string(f"ns=2;s=L{k}") for k in range(n)]


def test_a_server_certificate_refused_is_named_by_its_status(tmp_path: Path) -> None:
    pki = make_pki(tmp_path)
    cert = load_certificate_file(pki.server_cert)
    expired = load_certificate_file(expired_copy(pki.server_cert, pki.server_key,
                                                 tmp_path / "expired.der"))
    assert server_cert_reason("BadCertificateUntrusted", cert) == \
        "server certificate untrusted"
    assert server_cert_reason("BadCertificateTimeInvalid", expired) == \
        "server certificate expired"
    early = cert.not_valid_before_utc - datetime.timedelta(days=1)
    assert server_cert_reason("BadCertificateTimeInvalid", cert, early) == \
        "server certificate not yet valid"
    assert server_cert_reason("BadCertificateRevoked", cert) == "server certificate revoked"
    assert server_cert_reason("BadSomethingElse", cert) == "server certificate refused"


@pytest.mark.parametrize(("status", "reason"), [
    ("BadCertificateUntrusted", "gateway certificate rejected"),
    ("BadSecurityChecksFailed", "gateway certificate rejected"),
    ("BadCertificateTimeInvalid", "gateway certificate expired"),
    ("BadUserAccessDenied", "login refused"),
])
def test_a_refusal_by_the_server_is_named_by_its_status(status: str, reason: str) -> None:
    sec = OpcUaSecurity(policy="Basic256Sha256", mode="SignAndEncrypt",
                        certificate=Path("pki/client.der"), private_key=Path("pki/client.pem"),
                        trust_store=Path("pki/trusted"), username="gateway")
    err = map_error(UaStatusCodeError(getattr(StatusCodes, status)), device="dcs1",
                    endpoint="opc.tcp://x:4840", doing="connecting", security=sec, nodes=2)
    assert (err.kind, err.reason) == ("auth", reason)
    assert status in str(err)


def test_every_node_refused_is_one_device_error_named_by_the_status() -> None:
    n = 4
    unknown = np.full(n, StatusCodes.BadNodeIdUnknown, dtype=np.uint32)
    err = refused(unknown, _points(n), _ids(n), device="dcs1", endpoint="opc.tcp://x:4840")
    assert err is not None and (err.kind, err.reason) == \
        ("exception", "nodes refused (BadNodeIdUnknown)")
    assert "every one of its 4 nodes" in str(err) and "ns=2;s=L0" in str(err)
    assert "stiction-gateway browse opc.tcp://x:4840" in str(err)
    mixed = unknown.copy()
    mixed[1] = StatusCodes.BadUserAccessDenied
    err = refused(mixed, _points(n), _ids(n), device="dcs1", endpoint="e")
    assert err is not None and err.reason == "nodes refused"
    # a read with one good or uncertain point, or values that are not numbers, is data
    for k, code in ((2, StatusCodes.Good), (3, StatusCodes.UncertainLastUsableValue),
                    (0, StatusCodes.BadTypeMismatch)):
        some = unknown.copy()
        some[k] = code
        assert refused(some, _points(n), _ids(n), device="dcs1", endpoint="e") is None
