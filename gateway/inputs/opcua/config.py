"""Validation of the OPC UA parts of the gateway config, without any network.

``parse_opcua_device`` checks one ``devices:`` entry with ``protocol: opcua`` and
``parse_opcua_point`` one loop point (``op:`` / ``pv:``); each returns a frozen dataclass
(or None) and every problem found, one line each, naming the file, the device or loop and
the key, in the gateway config's format::

    gateway.yaml: device dcs1: key 'security.certificate': file not found: pki/client.der

Certificate, key, trust store and password files are checked at load: they exist, parse,
the key matches the certificate, the certificate carries an application URI and has not
expired, and the trust store holds at least one certificate. Relative paths are resolved
against the config file's directory (``base_dir``).
"""

from __future__ import annotations

import dataclasses
import datetime
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from asyncua import ua
from asyncua.ua.uaerrors import UaError
from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat

from ...config.schema import number
from ...wire.certs import application_uri_of, load_certificate_file, load_private_key_file

__all__ = [
    "DEFAULT_TIMEOUT_S",
    "MODES",
    "POLICIES",
    "OpcUaDeviceConfig",
    "OpcUaPoint",
    "OpcUaSecurity",
    "parse_opcua_device",
    "parse_opcua_point",
    "parse_plugin_device",
    "parse_security",
    "trust_store_files",
]

POLICIES = ("Basic256Sha256", "Aes128_Sha256_RsaOaep", "Aes256_Sha256_RsaPss")
"""Security policies (OPC UA names). The deprecated Basic128Rsa15 and Basic256 are refused."""
MODES = ("Sign", "SignAndEncrypt")
DEFAULT_TIMEOUT_S = 2.0
TRUST_SUFFIXES = (".der", ".pem")

DEVICE_KEYS = ("name", "protocol", "endpoint", "security", "poll_interval_s", "timeout_s",
               "max_nodes_per_read")
SECURITY_KEYS = ("policy", "mode", "certificate", "private_key", "server_certificate",
                 "trust_store", "username", "password_file")
POINT_KEYS = ("node", "scale", "offset")


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
    for servers with a small MaxNodesPerRead (0: every node in one call)."""

    name: str
    endpoint: str
    poll_interval_s: float
    timeout_s: float = DEFAULT_TIMEOUT_S
    security: OpcUaSecurity | None = None
    max_nodes_per_read: int = 0


@dataclasses.dataclass(frozen=True)
class OpcUaPoint:
    """One variable to read: ``node`` is a node id string (``ns=2;s=TIC205.OP``,
    ``ns=3;i=1001``, or ``nsu=<namespace URI>;s=...``), canonicalised."""

    node: str
    scale: float = 1.0
    offset: float = 0.0


class _Reader:
    """Reads one mapping, collecting problems; unread keys are reported as unknown."""

    def __init__(self, problems: list[str], prefix: str, raw: Any, key_prefix: str = "") -> None:
        self.problems = problems
        self.prefix = prefix  # "FILE: device dcs1"
        self.key_prefix = key_prefix  # "security." for nested keys
        self.raw: Mapping[str, Any] = raw if isinstance(raw, Mapping) else {}
        self.valid = isinstance(raw, Mapping)

    def error(self, key: str | None, message: str) -> None:
        where = [self.prefix] + ([f"key {self.key_prefix + key!r}"] if key else [])
        self.problems.append(": ".join([*where, message]))

    def get(self, key: str, conv: Callable[[Any], Any], *, required: bool,
            default: Any = None) -> Any:
        if key not in self.raw:
            if required:
                self.error(None, f"missing required key {self.key_prefix + key!r}")
            return default
        value = self.raw[key]
        try:
            return conv(value)
        except (TypeError, ValueError) as exc:
            self.error(key, f"{exc}, was {_describe(value)}")
            return None

    def unknown(self, known: tuple[str, ...]) -> None:
        for key in self.raw:
            if key not in known:
                self.error(None, f"unknown key {self.key_prefix + str(key)!r} "
                           f"(known: {', '.join(known)})")


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _string(value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise TypeError("must be a non-empty string")
    return value


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError("must be an integer")
    if value < 0:
        raise ValueError("must be >= 0 (0: no limit)")
    return value


def _choice(options: tuple[str, ...], hint: str = "") -> Callable[[Any], str]:
    def conv(value: Any) -> str:
        if value not in options:
            raise ValueError(f"must be one of {', '.join(options)}{hint}")
        return str(value)

    return conv


def _endpoint(value: Any) -> str:
    text = _string(value).strip()
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


def _path(base_dir: Path) -> Callable[[Any], tuple[str, Path]]:
    def conv(value: Any) -> tuple[str, Path]:
        text = _string(value)
        p = Path(text).expanduser()
        return text, p if p.is_absolute() else base_dir / p

    return conv


def _where_file(written: str, resolved: Path) -> str:
    return written if Path(written).expanduser().is_absolute() else f"{written} ({resolved})"


def trust_store_files(directory: Path) -> list[Path]:
    """The files asyncua's TrustStore loads from ``directory``: names ending .der/.pem."""
    return sorted(p for p in directory.iterdir()
                  if p.suffix.lower() in TRUST_SUFFIXES and p.is_file())


def parse_security(raw: Any, *, prefix: str, base_dir: Path,
                   problems: list[str]) -> OpcUaSecurity | None:
    """Validate a ``security:`` mapping; append problems (prefixed ``FILE: device X``)."""
    r = _Reader(problems, prefix, raw, "security.")
    if not r.valid:
        r.error(None, "key 'security': must be a mapping (leave it out for no security)")
        return None
    n_before = len(problems)
    policy = r.get("policy", _choice(POLICIES, " (leave out 'security' for no security)"),
                   required=True)
    mode = r.get("mode", _choice(MODES), required=True)
    path = _path(base_dir)
    cert_p = r.get("certificate", path, required=True)
    key_p = r.get("private_key", path, required=True)
    server_p = r.get("server_certificate", path, required=False)
    trust_p = r.get("trust_store", path, required=True)
    username = r.get("username", _string, required=False)
    pw_p = r.get("password_file", path, required=False)
    r.unknown(SECURITY_KEYS)

    now = datetime.datetime.now(datetime.UTC)
    cert = None
    if cert_p is not None:
        cert = _check_certificate(r, "certificate", *cert_p)
        if cert is not None:
            if application_uri_of(cert) is None:
                r.error("certificate", f"{cert_p[0]} has no application URI (a URI "
                        "subjectAltName); create it with 'stiction-gateway opcua-cert'")
            if cert.not_valid_after_utc < now:
                r.error("certificate", f"{cert_p[0]} expired on "
                        f"{cert.not_valid_after_utc.date().isoformat()}")
    if key_p is not None:
        written, resolved = key_p
        if _check_file(r, "private_key", written, resolved):
            try:
                key = load_private_key_file(resolved)
            except (ValueError, TypeError) as exc:
                r.error("private_key", f"{written} is not an unencrypted RSA private key "
                        f"(PEM or DER): {_first_line(exc)}")
            else:
                if cert is not None and _spki(key.public_key()) != _spki(cert.public_key()):
                    r.error("private_key", f"{written} does not belong to certificate "
                            f"{cert_p[0]}")
    if server_p is not None:
        _check_certificate(r, "server_certificate", *server_p)
    if trust_p is not None:
        _check_trust_store(r, *trust_p)
    if username is not None and pw_p is None:
        r.error(None, "missing key 'security.password_file' (needed with "
                "'security.username')")
    if pw_p is not None:
        if username is None:
            r.error("password_file", "needs 'security.username'")
        written, resolved = pw_p
        if _check_file(r, "password_file", written, resolved):
            try:
                first = resolved.read_text(encoding="utf-8").splitlines()
            except (OSError, UnicodeDecodeError) as exc:
                r.error("password_file", f"cannot read {written}: {exc}")
            else:
                if not first or not first[0]:
                    r.error("password_file", f"{written} is empty (the password is its "
                            "first line)")
    if len(problems) > n_before:
        return None
    return OpcUaSecurity(policy=policy, mode=mode, certificate=cert_p[1],
                         private_key=key_p[1], trust_store=trust_p[1],
                         server_certificate=server_p[1] if server_p else None,
                         username=username, password_file=pw_p[1] if pw_p else None)


def _spki(public_key: Any) -> bytes:
    return bytes(public_key.public_bytes(Encoding.DER, PublicFormat.SubjectPublicKeyInfo))


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0]


def _check_file(r: _Reader, key: str, written: str, resolved: Path) -> bool:
    if not resolved.exists():
        r.error(key, f"file not found: {_where_file(written, resolved)}")
        return False
    if not resolved.is_file():
        r.error(key, f"not a file: {_where_file(written, resolved)}")
        return False
    return True


def _check_certificate(r: _Reader, key: str, written: str, resolved: Path) -> Any:
    if not _check_file(r, key, written, resolved):
        return None
    try:
        return load_certificate_file(resolved)
    except (OSError, ValueError) as exc:
        r.error(key, f"{written} is not an X.509 certificate (DER or PEM): "
                f"{_first_line(exc)}")
        return None


def _check_trust_store(r: _Reader, written: str, resolved: Path) -> None:
    if not resolved.exists():
        r.error("trust_store", f"directory not found: {_where_file(written, resolved)}")
        return
    if not resolved.is_dir():
        r.error("trust_store", f"not a directory: {_where_file(written, resolved)}")
        return
    files = trust_store_files(resolved)
    if not files:
        r.error("trust_store", f"{written} holds no certificates (*.der, *.pem): copy the "
                "server's certificate there")
    for f in files:
        try:
            load_certificate_file(f)
        except (OSError, ValueError) as exc:
            r.error("trust_store", f"{f.name} in {written} is not an X.509 certificate: "
                    f"{_first_line(exc)}")


def parse_opcua_device(
    raw: Mapping[str, Any], *, source: str, base_dir: Path, where: str | None = None,
) -> tuple[OpcUaDeviceConfig | None, list[str]]:
    """Validate one ``devices:`` entry with ``protocol: opcua``.

    Returns the config (None if anything is wrong) and every problem, each prefixed with
    ``source`` and ``where`` (default ``device <name>``).
    """
    problems: list[str] = []
    name = raw.get("name") if isinstance(raw, Mapping) else None
    if where is None:
        where = f"device {name}" if isinstance(name, str) and name else "device (no name)"
    prefix = f"{source}: {where}"
    r = _Reader(problems, prefix, raw)
    if not r.valid:
        r.error(None, f"must be a mapping, was {type(raw).__name__}")
        return None, problems
    name = r.get("name", _string, required=True)
    protocol = r.get("protocol", _string, required=True)
    if protocol is not None and protocol != "opcua":
        r.error("protocol", f"must be 'opcua' here, was {protocol!r}")
    poll = r.get("poll_interval_s", number(positive=True), required=True)
    timeout = r.get("timeout_s", number(positive=True), required=False,
                    default=DEFAULT_TIMEOUT_S)
    r.unknown(DEVICE_KEYS)
    cfg = _own_keys(r, raw, prefix=prefix, base_dir=base_dir, problems=problems)
    if problems or cfg is None:
        return None, problems
    return dataclasses.replace(cfg, name=name, poll_interval_s=poll, timeout_s=timeout), problems


def _own_keys(r: _Reader, raw: Mapping[str, Any], *, prefix: str, base_dir: Path,
              problems: list[str]) -> OpcUaDeviceConfig | None:
    """The OPC UA keys of a device beyond the gateway's core keys (name, protocol,
    poll_interval_s, timeout_s), which are filled with placeholders."""
    n_before = len(problems)
    endpoint = r.get("endpoint", _endpoint, required=True)
    max_nodes = r.get("max_nodes_per_read", _count, required=False, default=0)
    security = None
    if "security" in raw and raw["security"] is not None:
        security = parse_security(raw["security"], prefix=prefix, base_dir=base_dir,
                                  problems=problems)
    if len(problems) > n_before:
        return None
    return OpcUaDeviceConfig(name="", endpoint=endpoint, poll_interval_s=1.0,
                             security=security, max_nodes_per_read=max_nodes)


def parse_plugin_device(sec: Any) -> OpcUaDeviceConfig | None:
    """The gateway config loader's plugin hook: read the OPC UA keys of a device from a
    :class:`gateway._schema.Section` (the core reads name, protocol, poll_interval_s and
    timeout_s); problems go to the section's list. Relative paths are resolved against the
    config file's directory (``problems.source``), or the working directory."""
    source = str(sec.problems.source)
    path = Path(source)
    base_dir = path.parent if path.is_file() else Path.cwd()
    own = ("endpoint", "max_nodes_per_read", "security")
    raw = {k: sec.raw_value(k) for k in own if sec.has(k)}  # raw_value marks them as read
    r = _Reader(sec.problems.lines, f"{source}: {sec.where}", raw)
    return _own_keys(r, raw, prefix=f"{source}: {sec.where}", base_dir=base_dir,
                     problems=sec.problems.lines)


def parse_node_id(value: Any) -> str:
    """A node id string, canonicalised; raises ValueError/TypeError with a reason."""
    text = _string(value).strip()
    try:
        node = ua.NodeId.from_string(text)
    except UaError:
        raise ValueError("is not an OPC UA node id (e.g. 'ns=2;s=TIC205.OP', 'ns=3;i=1001', "
                         "'nsu=urn:plant;s=TIC205.OP')") from None
    if node.Identifier in ("", b"", None):
        raise ValueError("has an empty identifier")
    return str(node.to_string())


def parse_opcua_point(
    raw: Any, *, source: str, loop: str, role: str,
) -> tuple[OpcUaPoint | None, list[str]]:
    """Validate one loop point ``{node: "ns=2;s=TIC205.OP", scale: 1.0, offset: 0.0}``
    (``role`` is ``op`` or ``pv``); problems read ``FILE: loop L: key 'op.node': ...``."""
    problems: list[str] = []
    r = _Reader(problems, f"{source}: loop {loop}", raw, f"{role}.")
    if not r.valid:
        problems.append(f"{source}: loop {loop}: key {role!r}: must be a mapping like "
                        f"{{node: \"ns=2;s={loop}.{role.upper()}\"}}, was {_describe(raw)}")
        return None, problems
    node = r.get("node", parse_node_id, required=True)
    scale = r.get("scale", number(), required=False, default=1.0)
    offset = r.get("offset", number(), required=False, default=0.0)
    if scale == 0.0:
        r.error("scale", "must not be 0")
    r.unknown(POINT_KEYS)
    if problems:
        return None, problems
    return OpcUaPoint(node=node, scale=scale, offset=offset), problems
