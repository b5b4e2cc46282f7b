"""``make_certificate`` / ``stiction-gateway opcua-cert`` and the plc-sim server's surface."""

from __future__ import annotations

import asyncio
import ipaddress
import stat
from pathlib import Path

import numpy as np
import pytest
from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID

from gateway.cli import main as gateway_main
from gateway.wire.certs import (
    application_uri_of,
    load_certificate_file,
    load_private_key_file,
    main,
    make_certificate,
)
from plcsim.opcua import OpcUaPlcServer, ServerSecurity


def test_make_certificate_fits_opc_ua(tmp_path: Path) -> None:
    cert = make_certificate(tmp_path / "pki/client.der", tmp_path / "pki/client.pem",
                            common_name="stiction-gateway",
                            application_uri="urn:edge1:stiction-gateway",
                            hostnames=["edge1", "10.0.0.5"], days=30)
    assert load_certificate_file(tmp_path / "pki/client.der") == cert
    key = load_private_key_file(tmp_path / "pki/client.pem")
    assert key.public_key().public_numbers() == cert.public_key().public_numbers()  # type: ignore[union-attr]
    assert key.key_size == 2048
    assert stat.S_IMODE((tmp_path / "pki/client.pem").stat().st_mode) == 0o600
    assert application_uri_of(cert) == "urn:edge1:stiction-gateway"
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert san.get_values_for_type(x509.DNSName) == ["edge1"]
    assert san.get_values_for_type(x509.IPAddress) == [ipaddress.ip_address("10.0.0.5")]
    usage = cert.extensions.get_extension_for_class(x509.KeyUsage).value
    assert usage.digital_signature
    assert usage.key_encipherment
    assert usage.data_encipherment
    eku = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert list(eku) == [ExtendedKeyUsageOID.CLIENT_AUTH]
    assert (cert.not_valid_after_utc - cert.not_valid_before_utc).days == 30


def test_make_certificate_refuses_to_overwrite(tmp_path: Path) -> None:
    args = {"common_name": "a", "application_uri": "urn:a", "hostnames": ["a"]}
    make_certificate(tmp_path / "c.der", tmp_path / "k.pem", **args)  # type: ignore[arg-type]
    with pytest.raises(FileExistsError, match=r"c\.der exists \(use overwrite to replace it\)"):
        make_certificate(tmp_path / "c.der", tmp_path / "k.pem", **args)  # type: ignore[arg-type]
    make_certificate(tmp_path / "c.der", tmp_path / "k.pem", overwrite=True, **args)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="application_uri must not be empty"):
        make_certificate(tmp_path / "d.der", tmp_path / "d.pem", common_name="a",
                         application_uri="", hostnames=[])


def test_opcua_cert_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cert, key = tmp_path / "pki/client.der", tmp_path / "pki/client.pem"
    assert main(["--cert", str(cert), "--key", str(key), "--uri", "urn:t:gw",
                 "--host", "edge1"]) == 0
    out = capsys.readouterr().out
    assert f"certificate: {cert} (CN=stiction-gateway, SHA-1 thumbprint " in out
    assert "application URI: urn:t:gw" in out
    assert main(["--cert", str(cert), "--key", str(key)]) == 1
    assert "exists (use --force to replace it)" in capsys.readouterr().err
    assert main(["--cert", str(cert), "--key", str(key), "--server", "--force"]) == 0
    eku = load_certificate_file(cert).extensions.get_extension_for_class(x509.ExtendedKeyUsage)
    assert list(eku.value) == [ExtendedKeyUsageOID.SERVER_AUTH]


def test_opcua_cert_is_a_gateway_subcommand(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    cert, key = tmp_path / "c.der", tmp_path / "c.pem"
    assert gateway_main(["opcua-cert", "--cert", str(cert), "--key", str(key),
                         "--uri", "urn:t:gw"]) == 0
    assert "application URI: urn:t:gw" in capsys.readouterr().out
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    with pytest.raises(SystemExit) as info:
        gateway_main(["opcua-cert", "--bogus"])
    assert info.value.code == 2


def test_plcsim_server_argument_checks(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="loops: names must be unique"):
        OpcUaPlcServer(["A", "A"])
    with pytest.raises(ValueError, match=r"port must be in 0\.\.65535 \(0: a free port\), "
                       r"was 70000"):
        OpcUaPlcServer(["A"], port=70000)
    with pytest.raises(ValueError, match=r"policies: unknown policy/mode \('Basic256', "
                       r"'Sign'\)"):
        ServerSecurity(tmp_path / "c", tmp_path / "k", policies=(("Basic256", "Sign"),))
    server = OpcUaPlcServer(["A", "B"])
    assert server.node_id("A", "op") == "ns=2;s=A.OP"
    assert server.endpoint == "opc.tcp://127.0.0.1:4840"


def test_plcsim_update_checks_shapes_before_start() -> None:
    server = OpcUaPlcServer(["A", "B"])
    with pytest.raises(ValueError, match="op, pv and position must have 2 values, had 3, 2 and 3"):
        asyncio.run(server.update(np.zeros(3), np.zeros(2)))
    asyncio.run(server.update([1.0, 2.0], [3.0, 4.0]))  # kept, served once started
