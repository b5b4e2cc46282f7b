"""Validation of OPC UA devices and points: every problem at once, with exact messages."""

from __future__ import annotations

import datetime
import shutil
from pathlib import Path
from typing import Any

import pytest
from _opcua_support import Pki, make_pki
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.x509.oid import NameOID

from gateway.config import Config, parse_config
from gateway.errors import ConfigError
from gateway.inputs.opcua.config import OpcUaPoint, OpcUaSecurity
from gateway.wire.certs import load_certificate_file, load_private_key_file, make_certificate

SRC = "gateway.yaml"


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    """The PKI laid out as the docs suggest, beside the config file: pki/, secrets/."""
    base = tmp_path_factory.mktemp("cfg")
    p = make_pki(base / "pki")
    (base / "secrets").mkdir()
    shutil.copy(p.password_file, base / "secrets" / "opcua.pw")
    (base / SRC).write_text("# relative paths are resolved against this file's directory\n")
    return p


def base_dir(pki: Pki) -> Path:
    return pki.root.parent


def raw_device(**changes: Any) -> dict[str, Any]:
    raw: dict[str, Any] = {
        "name": "dcs1",
        "protocol": "opcua",
        "endpoint": "opc.tcp://127.0.0.1:4840",
        "security": {
            "policy": "Basic256Sha256",
            "mode": "SignAndEncrypt",
            "certificate": "pki/client.der",
            "private_key": "pki/client.pem",
            "server_certificate": "pki/server.der",
            "trust_store": "pki/trusted/",
            "username": "gateway",
            "password_file": "secrets/opcua.pw",
        },
        "poll_interval_s": 1.0,
        "timeout_s": 2.0,
    }
    for key, value in changes.items():
        if key.startswith("security."):
            sub = key.removeprefix("security.")
            if value is None:
                raw["security"].pop(sub)
            else:
                raw["security"][sub] = value
        elif value is None:
            raw.pop(key)
        else:
            raw[key] = value
    return raw


def parse(base: Path, device: Any, op: Any = None, pv: Any = None
          ) -> tuple[Config | None, list[str]]:
    """The config of ``device`` and one loop reading ``op``/``pv`` from it, through the
    gateway's loader (the file named as the source lies in ``base``), and its problems
    with the file named ``gateway.yaml``."""
    loop = {"name": "TIC205", "device": "dcs1",
            "op": {"node": "ns=2;s=TIC205.OP"} if op is None else op,
            "pv": {"node": "ns=2;s=TIC205.PV"} if pv is None else pv, "result_address": 0}
    source = str(base / SRC)
    try:
        return parse_config({"devices": [device], "loops": [loop]}, source), []
    except ConfigError as exc:
        return None, [line.replace(source, SRC, 1) for line in exc.problems]


def problems(pki: Pki, **changes: Any) -> list[str]:
    cfg, found = parse(base_dir(pki), raw_device(**changes))
    assert (cfg is None) == bool(found)
    return found


def test_the_issue_example_loads_with_paths_resolved(pki: Pki) -> None:
    cfg, found = parse(base_dir(pki), raw_device())
    assert found == []
    assert cfg is not None
    dev = cfg.devices[0]
    assert (dev.name, dev.protocol, dev.poll_interval_s, dev.timeout_s) == ("dcs1", "opcua",
                                                                            1.0, 2.0)
    assert dev.options.endpoint == "opc.tcp://127.0.0.1:4840"
    assert dev.options.max_nodes_per_read == 0
    root = base_dir(pki)
    assert dev.options.security == OpcUaSecurity(
        policy="Basic256Sha256", mode="SignAndEncrypt",
        certificate=root / "pki/client.der", private_key=root / "pki/client.pem",
        trust_store=root / "pki/trusted", server_certificate=root / "pki/server.der",
        username="gateway", password_file=root / "secrets/opcua.pw")


def test_security_is_optional_and_minimal_security_is_enough(pki: Pki) -> None:
    cfg, found = parse(base_dir(pki), raw_device(security=None, timeout_s=0.5,
                                                 max_nodes_per_read=100))
    assert found == []
    assert cfg is not None
    opts = cfg.devices[0].options
    assert opts.security is None
    assert (cfg.devices[0].timeout_s, opts.max_nodes_per_read) == (0.5, 100)
    found = problems(pki, **{"security.server_certificate": None, "security.username": None,
                             "security.password_file": None, "security.mode": "Sign"})
    assert found == []


def test_missing_certificate_file_is_named(pki: Pki) -> None:
    root = base_dir(pki)
    assert problems(pki, **{"security.certificate": "pki/missing.der"}) == [
        f"gateway.yaml: device dcs1: key 'security.certificate': file not found: "
        f"pki/missing.der ({root / 'pki/missing.der'})",
    ]
    assert problems(pki, **{"security.server_certificate": "/nonexistent/server.der",
                            "security.password_file": "secrets/nope.pw"}) == [
        "gateway.yaml: device dcs1: key 'security.server_certificate': file not found: "
        "/nonexistent/server.der",
        f"gateway.yaml: device dcs1: key 'security.password_file': file not found: "
        f"secrets/nope.pw ({root / 'secrets/nope.pw'})",
    ]


def test_unknown_keys_are_errors(pki: Pki) -> None:
    assert problems(pki, poll_intervall_s=2.0, **{"security.pasword_file": "x"}) == [
        "gateway.yaml: device dcs1: unknown key 'security.pasword_file' (known: policy, mode, "
        "certificate, private_key, server_certificate, trust_store, username, password_file)",
        "gateway.yaml: device dcs1: unknown key 'poll_intervall_s'",
    ]


def test_bad_policy_and_mode(pki: Pki) -> None:
    assert problems(pki, **{"security.policy": "Basic128Rsa15",
                            "security.mode": "Encrypt"}) == [
        "gateway.yaml: device dcs1: key 'security.policy': must be one of Basic256Sha256, "
        "Aes128_Sha256_RsaOaep, Aes256_Sha256_RsaPss (leave out 'security' for no security), "
        "was 'Basic128Rsa15'",
        "gateway.yaml: device dcs1: key 'security.mode': must be one of Sign, SignAndEncrypt, "
        "was 'Encrypt'",
    ]


def test_missing_keys_and_bad_types_reported_together(pki: Pki) -> None:
    assert problems(pki, endpoint=None, poll_interval_s="1s", timeout_s=0,
                    **{"security.trust_store": None, "security.policy": None}) == [
        "gateway.yaml: device dcs1: key 'poll_interval_s': must be a number, was '1s'",
        "gateway.yaml: device dcs1: key 'timeout_s': must be > 0, was 0",
        "gateway.yaml: device dcs1: missing required key 'endpoint'",
        "gateway.yaml: device dcs1: missing required key 'security.policy'",
        "gateway.yaml: device dcs1: missing required key 'security.trust_store'",
    ]


@pytest.mark.parametrize(("endpoint", "message"), [
    ("http://127.0.0.1:4840", "must be an opc.tcp://host:port URL"),
    ("opc.tcp://:4840", "has no host name"),
    ("opc.tcp://plc:99999", "has a port outside 1..65535"),
    ("opc.tcp://user:pw@plc:4840", "must not hold a user name or password (use "
     "security.username and security.password_file)"),
])
def test_bad_endpoint(pki: Pki, endpoint: str, message: str) -> None:
    assert problems(pki, endpoint=endpoint, security=None) == [
        f"gateway.yaml: device dcs1: key 'endpoint': {message}, was {endpoint!r}"]


def test_username_and_password_file_go_together(pki: Pki) -> None:
    assert problems(pki, **{"security.password_file": None}) == [
        "gateway.yaml: device dcs1: missing key 'security.password_file' (needed with "
        "'security.username')"]
    assert problems(pki, **{"security.username": None}) == [
        "gateway.yaml: device dcs1: key 'security.password_file': needs 'security.username'"]


def test_certificate_contents_are_checked_at_load(pki: Pki, tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notacert.pem").write_text("hello")
    (tmp_path / "blank.pw").write_text("\n")
    found = problems(pki, **{
        "security.certificate": str(pki.client_key),  # a key, not a certificate
        "security.private_key": str(pki.server_key),
        "security.trust_store": str(tmp_path / "empty"),
        "security.password_file": str(tmp_path / "blank.pw"),
    })
    assert found == [
        f"gateway.yaml: device dcs1: key 'security.certificate': {pki.client_key} is not an "
        "X.509 certificate (DER or PEM): Valid PEM but no BEGIN CERTIFICATE/END CERTIFICATE "
        "delimiters. Are you sure this is a certificate?",
        f"gateway.yaml: device dcs1: key 'security.trust_store': {tmp_path / 'empty'} holds no "
        "certificates (*.der, *.pem): copy the server's certificate there",
        f"gateway.yaml: device dcs1: key 'security.password_file': {tmp_path / 'blank.pw'} is "
        "empty (the password is its first line)",
    ]
    found = problems(pki, **{"security.private_key": str(pki.server_key),
                             "security.trust_store": str(tmp_path / "junk")})
    assert found[0] == (
        f"gateway.yaml: device dcs1: key 'security.private_key': {pki.server_key} does not "
        "belong to certificate pki/client.der")
    assert found[1].startswith(
        f"gateway.yaml: device dcs1: key 'security.trust_store': notacert.pem in "
        f"{tmp_path / 'junk'} is not an X.509 certificate")
    assert len(found) == 2


def test_certificate_without_uri_or_expired(pki: Pki, tmp_path: Path) -> None:
    key = load_private_key_file(pki.client_key)
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "old")])
    now = datetime.datetime.now(datetime.UTC)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(1)
            .not_valid_before(now - datetime.timedelta(days=10))
            .not_valid_after(now - datetime.timedelta(days=1))
            .sign(key, hashes.SHA256()))
    (tmp_path / "old.der").write_bytes(cert.public_bytes(serialization.Encoding.DER))
    found = problems(pki, **{"security.certificate": str(tmp_path / "old.der")})
    day = (now - datetime.timedelta(days=1)).date().isoformat()
    assert found == [
        f"gateway.yaml: device dcs1: key 'security.certificate': {tmp_path / 'old.der'} has no "
        "application URI (a URI subjectAltName); create it with 'stiction-gateway opcua-cert'",
        f"gateway.yaml: device dcs1: key 'security.certificate': {tmp_path / 'old.der'} "
        f"expired on {day}",
    ]


def test_pem_certificates_and_other_names_are_accepted(pki: Pki, tmp_path: Path) -> None:
    pem = load_certificate_file(pki.client_cert).public_bytes(serialization.Encoding.PEM)
    (tmp_path / "client.crt").write_bytes(pem)
    assert problems(pki, **{"security.certificate": str(tmp_path / "client.crt")}) == []


def test_security_not_a_mapping(pki: Pki) -> None:
    assert problems(pki, security="yes") == [
        "gateway.yaml: device dcs1: key 'security': must be a mapping (leave it out for no "
        "security)",
    ]


def test_point_node_ids(pki: Pki) -> None:
    cfg, found = parse(base_dir(pki), raw_device(security=None),
                       op={"node": "ns=3;i=1001", "scale": 0.1, "offset": -5},
                       pv={"node": "nsu=urn:plant;s=TIC205.PV"})
    assert found == []
    assert cfg is not None
    op, pv = cfg.loops[0].op, cfg.loops[0].pv
    assert (op.address, op.scale, op.offset) == (OpcUaPoint("ns=3;i=1001"), 0.1, -5.0)
    assert pv.address.node == "s=TIC205.PV;nsu=urn:plant"


def test_point_problems(pki: Pki) -> None:
    def found(op: Any = None, pv: Any = None) -> list[str]:
        return parse(base_dir(pki), raw_device(security=None), op, pv)[1]

    assert found(op={"node": "TIC205.OP", "scale": 0, "adress": 3}) == [
        "gateway.yaml: loop TIC205: key 'op.scale': must not be 0",
        "gateway.yaml: loop TIC205: key 'op.node': is not an OPC UA node id (e.g. "
        "'ns=2;s=TIC205.OP', 'ns=3;i=1001', 'nsu=urn:plant;s=TIC205.OP'), was 'TIC205.OP'",
        "gateway.yaml: loop TIC205: unknown key 'op.adress'",
    ]
    assert found(pv={"scale": 1.0}) == [
        "gateway.yaml: loop TIC205: missing required key 'pv.node'"]
    assert found(pv={"node": "ns=2;s="}) == [
        "gateway.yaml: loop TIC205: key 'pv.node': has an empty identifier, was 'ns=2;s='"]
    assert found(pv="ns=2;s=X") == [
        "gateway.yaml: loop TIC205: key 'pv': must be a mapping, was a string"]


def test_certificate_made_by_the_tool_validates(tmp_path: Path) -> None:
    make_certificate(tmp_path / "pki/client.der", tmp_path / "pki/client.pem",
                     common_name="gw", application_uri="urn:x:gw", hostnames=["gw"])
    make_certificate(tmp_path / "pki/trusted/server.der", tmp_path / "srv.pem",
                     common_name="plc", application_uri="urn:x:plc", hostnames=["plc"],
                     server=True)
    raw = raw_device(**{"security.server_certificate": "pki/trusted/server.der",
                        "security.username": None, "security.password_file": None})
    (tmp_path / SRC).write_text("")
    cfg, found = parse(tmp_path, raw)
    assert found == []
    assert cfg is not None
