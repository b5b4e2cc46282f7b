"""The OPC UA keys of a device and of a point, read with the config's one validator.

Certificate, key, trust store and password files are checked at load, without any network:
they exist, parse, the key matches the certificate, the certificate carries an application
URI and has not expired, and the trust store holds at least one certificate. Relative paths
are resolved against the config file's directory. Problems read like every other config
problem::

    gateway.yaml: device dcs1: key 'security.certificate': file not found: pki/client.der
"""

from __future__ import annotations

import dataclasses
import datetime
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from asyncua import ua
from asyncua.ua.uaerrors import UaError
from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat

from ...config.schema import MISSING, Section, choice
from ...wire.certs import application_uri_of, load_certificate_file, load_private_key_file

__all__ = [
    "MODES",
    "POINT_ADDRESS_KEY",
    "POLICIES",
    "OpcUaDeviceConfig",
    "OpcUaPoint",
    "OpcUaSecurity",
    "parse_device",
    "parse_node_id",
    "parse_point",
    "trust_store_files",
]

POINT_ADDRESS_KEY = "node"
"""The point key a tag list's op/pv cell fills (a node id; gateway.config.tags)."""

POLICIES = ("Basic256Sha256", "Aes128_Sha256_RsaOaep", "Aes256_Sha256_RsaPss")
"""Security policies (OPC UA names). The deprecated Basic128Rsa15 and Basic256 are refused."""
MODES = ("Sign", "SignAndEncrypt")
DEFAULT_TIMEOUT_S = 2.0
TRUST_SUFFIXES = (".der", ".pem")


@dataclasses.dataclass(frozen=True)
class OpcUaSecurity:
    """A signed (``Sign``) or signed and encrypted (``SignAndEncrypt``) session.

    Paths are absolute. ``server_certificate`` pins the server's certificate; without it
    the certificate the server presents is used, after validation against
    ``trust_store`` (a directory of trusted certificates, DER or PEM), which always
    happens. ``username`` logs in with the password in ``password_file`` (first line).
    """

    policy: str
    mode: str
    certificate: Path
    private_key: Path
    trust_store: Path
    server_certificate: Path | None = None
    username: str | None = None
    password_file: Path | None = None


@dataclasses.dataclass(frozen=True)
class OpcUaDeviceConfig:
    """One OPC UA server. ``max_nodes_per_read`` splits a poll into several Read calls
    for servers with a small MaxNodesPerRead (0: every node in one call). ``name``,
    ``poll_interval_s`` and ``timeout_s`` are the device's core keys, filled in when the
    source is built (the loader stores placeholders: the fields and their values are part
    of the windows' signature in state files, so they stay as they were)."""

    name: str
    endpoint: str
    poll_interval_s: float
    timeout_s: float = DEFAULT_TIMEOUT_S
    security: OpcUaSecurity | None = None
    max_nodes_per_read: int = 0


@dataclasses.dataclass(frozen=True)
class OpcUaPoint:
    """One variable to read: ``node`` is a node id string (``ns=2;s=TIC205.OP``,
    ``ns=3;i=1001``, or ``nsu=<namespace URI>;s=...``), canonicalised. (``scale`` and
    ``offset`` are the point's core keys; these fields stay for the same reason.)"""

    node: str
    scale: float = 1.0
    offset: float = 0.0

    def __str__(self) -> str:
        return self.node


# ------------------------------------------------------------------ converters


def _text(value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise TypeError("must be a non-empty string")
    return value


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError("must be an integer")
    if value < 0:
        raise ValueError("must be >= 0 (0: no limit)")
    return value


def _endpoint(value: Any) -> str:
    text = _text(value).strip()
    url = urlparse(text)
    if url.scheme != "opc.tcp":
        raise ValueError("must be an opc.tcp://host:port URL")
    if not url.hostname:
        raise ValueError("has no host name")
    try:
        url.port  # noqa: B018 - raises ValueError when out of range
    except ValueError:
        raise ValueError("has a port outside 1..65535") from None
    if url.username or url.password:
        raise ValueError("must not hold a user name or password (use security.username "
                         "and security.password_file)")
    return text


def parse_node_id(value: Any) -> str:
    """A node id string, canonicalised; raises ValueError/TypeError with a reason."""
    text = _text(value).strip()
    try:
        node = ua.NodeId.from_string(text)
    except UaError:
        raise ValueError("is not an OPC UA node id (e.g. 'ns=2;s=TIC205.OP', 'ns=3;i=1001', "
                         "'nsu=urn:plant;s=TIC205.OP')") from None
    if node.Identifier in ("", b"", None):
        raise ValueError("has an empty identifier")
    return str(node.to_string())


# ------------------------------------------------------------------ plugin hooks


def parse_device(sec: Section) -> OpcUaDeviceConfig | Any:
    """The device's OPC UA keys (the loader reads name, protocol, poll_interval_s and
    timeout_s). Relative paths are resolved against the config file's directory."""
    endpoint = sec.req("endpoint", _endpoint)
    max_nodes = sec.opt("max_nodes_per_read", _count, 0)
    security = None
    raw = sec.raw_value("security")
    if raw is not MISSING and raw is not None:
        if isinstance(raw, dict):
            security = _parse_security(sec.sub("security"), _base_dir(sec.problems.source))
        else:
            sec.error("security", "must be a mapping (leave it out for no security)")
            security = MISSING
    if MISSING in (endpoint, max_nodes, security):
        return MISSING
    return OpcUaDeviceConfig(name="", endpoint=endpoint, poll_interval_s=1.0,
                             security=security, max_nodes_per_read=max_nodes)


def parse_point(sec: Section, options: OpcUaDeviceConfig | None) -> OpcUaPoint | Any:
    """A point's ``node`` (the loader reads ``scale``, ``offset`` and ``range``)."""
    node = sec.req("node", parse_node_id)
    return MISSING if node is MISSING else OpcUaPoint(node)


def _base_dir(source: str) -> Path:
    path = Path(source)
    return path.parent if path.is_file() else Path.cwd()


# ------------------------------------------------------------------ security


def _parse_security(sec: Section, base_dir: Path) -> OpcUaSecurity | Any:
    """A ``security:`` mapping; its files are checked once every key has been read."""
    before = len(sec.problems.lines)

    def path(value: Any) -> tuple[str, Path]:
        text = _text(value)
        p = Path(text).expanduser()
        return text, p if p.is_absolute() else base_dir / p

    policy = sec.req("policy", choice(POLICIES, " (leave out 'security' for no security)"))
    mode = sec.req("mode", choice(MODES))
    cert_p = sec.req("certificate", path)
    key_p = sec.req("private_key", path)
    server_p = sec.opt("server_certificate", path, None)
    trust_p = sec.req("trust_store", path)
    username = sec.opt("username", _text, None)
    pw_p = sec.opt("password_file", path, None)
    sec.done(list_known=True)
    files = _SecurityFiles(sec)
    cert = files.certificate(cert_p)
    files.private_key(key_p, cert, cert_p)
    if server_p not in (None, MISSING):
        files.check_certificate("server_certificate", *server_p)
    if trust_p is not MISSING:
        files.trust_store(*trust_p)
    if username is None and pw_p not in (None, MISSING):
        sec.error("password_file", "needs 'security.username'")
    if username is not None and pw_p is None:
        sec.error(None, "missing key 'security.password_file' (needed with "
                  "'security.username')")
    if pw_p not in (None, MISSING):
        files.password_file(*pw_p)
    if len(sec.problems.lines) > before:
        return MISSING
    return OpcUaSecurity(policy=policy, mode=mode, certificate=cert_p[1],
                         private_key=key_p[1], trust_store=trust_p[1],
                         server_certificate=server_p[1] if server_p else None,
                         username=username, password_file=pw_p[1] if pw_p else None)


def trust_store_files(directory: Path) -> list[Path]:
    """The files asyncua's TrustStore loads from ``directory``: names ending .der/.pem."""
    return sorted(p for p in directory.iterdir()
                  if p.suffix.lower() in TRUST_SUFFIXES and p.is_file())


def _where(written: str, resolved: Path) -> str:
    return written if Path(written).expanduser().is_absolute() else f"{written} ({resolved})"


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0]


def _spki(public_key: Any) -> bytes:
    return bytes(public_key.public_bytes(Encoding.DER, PublicFormat.SubjectPublicKeyInfo))


class _SecurityFiles:
    """Checks of the files a ``security:`` section names; problems go to ``sec``."""

    def __init__(self, sec: Section) -> None:
        self.sec = sec

    def exists(self, key: str, written: str, resolved: Path) -> bool:
        if not resolved.exists():
            self.sec.error(key, f"file not found: {_where(written, resolved)}")
            return False
        if not resolved.is_file():
            self.sec.error(key, f"not a file: {_where(written, resolved)}")
            return False
        return True

    def check_certificate(self, key: str, written: str, resolved: Path) -> Any:
        if not self.exists(key, written, resolved):
            return None
        try:
            return load_certificate_file(resolved)
        except (OSError, ValueError) as exc:
            self.sec.error(key, f"{written} is not an X.509 certificate (DER or PEM): "
                           f"{_first_line(exc)}")
            return None

    def certificate(self, cert_p: Any) -> Any:
        if cert_p is MISSING:
            return None
        cert = self.check_certificate("certificate", *cert_p)
        if cert is not None:
            if application_uri_of(cert) is None:
                self.sec.error("certificate", f"{cert_p[0]} has no application URI (a URI "
                               "subjectAltName); create it with 'stiction-gateway opcua-cert'")
            if cert.not_valid_after_utc < datetime.datetime.now(datetime.UTC):
                self.sec.error("certificate", f"{cert_p[0]} expired on "
                               f"{cert.not_valid_after_utc.date().isoformat()}")
        return cert

    def private_key(self, key_p: Any, cert: Any, cert_p: Any) -> None:
        if key_p is MISSING or not self.exists("private_key", *key_p):
            return
        written, resolved = key_p
        try:
            key = load_private_key_file(resolved)
        except (ValueError, TypeError) as exc:
            self.sec.error("private_key", f"{written} is not an unencrypted RSA private key "
                           f"(PEM or DER): {_first_line(exc)}")
            return
        if cert is not None and _spki(key.public_key()) != _spki(cert.public_key()):
            self.sec.error("private_key", f"{written} does not belong to certificate "
                           f"{cert_p[0]}")

    def trust_store(self, written: str, resolved: Path) -> None:
        if not resolved.exists():
            self.sec.error("trust_store", f"directory not found: {_where(written, resolved)}")
            return
        if not resolved.is_dir():
            self.sec.error("trust_store", f"not a directory: {_where(written, resolved)}")
            return
        files = trust_store_files(resolved)
        if not files:
            self.sec.error("trust_store", f"{written} holds no certificates (*.der, *.pem): "
                           "copy the server's certificate there")
        for f in files:
            try:
                load_certificate_file(f)
            except (OSError, ValueError) as exc:
                self.sec.error("trust_store", f"{f.name} in {written} is not an X.509 "
                               f"certificate: {_first_line(exc)}")

    def password_file(self, written: str, resolved: Path) -> None:
        if not self.exists("password_file", written, resolved):
            return
        try:
            first = resolved.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            self.sec.error("password_file", f"cannot read {written}: {exc}")
            return
        if not first or not first[0]:
            self.sec.error("password_file", f"{written} is empty (the password is its first "
                           "line)")
