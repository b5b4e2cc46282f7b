"""Shared helpers of the OPC UA tests: a throw-away PKI, free ports, bounded asyncio runs."""

from __future__ import annotations

import asyncio
import dataclasses
import shutil
import socket
from collections.abc import Coroutine
from pathlib import Path
from typing import Any, TypeVar

from gateway.inputs.opcua.config import OpcUaDeviceConfig, OpcUaSecurity
from gateway.wire.certs import make_certificate
from plcsim.opcua import ServerSecurity

T = TypeVar("T")

USER = "gateway"
PASSWORD = "s3cret-Ventil"
CLIENT_URI = "urn:test:stiction-gateway"
SERVER_URI = "urn:test:plc-sim"


@dataclasses.dataclass(frozen=True)
class Pki:
    """Files of one test PKI (see :func:`make_pki`)."""

    root: Path
    client_cert: Path
    client_key: Path
    server_cert: Path
    server_key: Path
    other_cert: Path  # a second server's certificate (not the test server's)
    other_key: Path
    trusted: Path  # trust store holding server_cert
    untrusted: Path  # trust store holding only other_cert
    trusted_clients: Path  # the server's trust list holding client_cert
    password_file: Path
    wrong_password_file: Path


def make_pki(root: Path) -> Pki:
    hosts = ["localhost", "127.0.0.1", socket.gethostname()]
    make_certificate(root / "client.der", root / "client.pem", common_name="test gateway",
                     application_uri=CLIENT_URI, hostnames=hosts)
    make_certificate(root / "server.der", root / "server.pem", common_name="test plc-sim",
                     application_uri=SERVER_URI, hostnames=hosts, server=True)
    make_certificate(root / "other.der", root / "other.pem", common_name="other server",
                     application_uri=SERVER_URI, hostnames=hosts, server=True)
    for name, cert in (("trusted", "server.der"), ("untrusted", "other.der"),
                       ("trusted_clients", "client.der")):
        (root / name).mkdir()
        shutil.copy(root / cert, root / name / cert)
    (root / "opcua.pw").write_text(PASSWORD + "\n")
    (root / "wrong.pw").write_text("not-the-password\n")
    return Pki(root, root / "client.der", root / "client.pem", root / "server.der",
               root / "server.pem", root / "other.der", root / "other.pem", root / "trusted",
               root / "untrusted", root / "trusted_clients", root / "opcua.pw",
               root / "wrong.pw")


def server_security(pki: Pki, *, mode: str = "SignAndEncrypt",
                    policy: str = "Basic256Sha256", users: bool = True,
                    trusted_clients: bool = False) -> ServerSecurity:
    return ServerSecurity(pki.server_cert, pki.server_key, policies=((policy, mode),),
                          users={USER: PASSWORD} if users else None,
                          trusted_clients=pki.trusted_clients if trusted_clients else None)


def client_security(pki: Pki, *, mode: str = "SignAndEncrypt",
                    policy: str = "Basic256Sha256", **changes: Any) -> OpcUaSecurity:
    sec = OpcUaSecurity(policy=policy, mode=mode, certificate=pki.client_cert,
                        private_key=pki.client_key, trust_store=pki.trusted,
                        username=USER, password_file=pki.password_file)
    return dataclasses.replace(sec, **changes)


def device(port: int, security: OpcUaSecurity | None = None, **changes: Any
           ) -> OpcUaDeviceConfig:
    cfg = OpcUaDeviceConfig(name="dcs1", endpoint=f"opc.tcp://127.0.0.1:{port}",
                            poll_interval_s=1.0, timeout_s=1.0, security=security)
    return dataclasses.replace(cfg, **changes)


def run(coro: Coroutine[Any, Any, T], timeout: float = 30.0) -> T:
    """Run a test coroutine with a hard time bound."""

    async def bounded() -> T:
        async with asyncio.timeout(timeout):
            return await coro

    return asyncio.run(bounded())


def expired_copy(cert_path: Path, key_path: Path, out: Path, *, days_ago: int = 1) -> Path:
    """A copy of the certificate ``cert_path`` (same subject, key and extensions, signed
    again with ``key_path``) whose validity ended ``days_ago`` days ago (DER)."""
    import datetime  # noqa: PLC0415

    from cryptography import x509  # noqa: PLC0415
    from cryptography.hazmat.primitives import hashes, serialization  # noqa: PLC0415

    from gateway.wire.certs import load_certificate_file, load_private_key_file  # noqa: PLC0415

    cert, key = load_certificate_file(cert_path), load_private_key_file(key_path)
    now = datetime.datetime.now(datetime.UTC)
    builder = (x509.CertificateBuilder().subject_name(cert.subject).issuer_name(cert.issuer)
               .public_key(cert.public_key()).serial_number(x509.random_serial_number())
               .not_valid_before(now - datetime.timedelta(days=30 + days_ago))
               .not_valid_after(now - datetime.timedelta(days=days_ago)))
    for ext in cert.extensions:
        builder = builder.add_extension(ext.value, critical=ext.critical)
    out.write_bytes(builder.sign(key, hashes.SHA256()).public_bytes(serialization.Encoding.DER))
    return out
