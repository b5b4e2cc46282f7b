"""OPC UA input adapter: one asyncua client (one session) per device.

Every poll reads the Value attribute of all of the device's nodes in one Read service call
(``Client.read_attributes``; several only when ``max_nodes_per_read`` asks for it), and
keeps each value's StatusCode:

=======================  ===========================================================
status / value           sample
=======================  ===========================================================
Good, finite number      value * scale + offset, ``Quality.GOOD``
Uncertain                NaN, ``Quality.UNCERTAIN`` (a gap: analysis never uses it)
Bad (incl. a node that   NaN, ``Quality.BAD``; the device's other points go on
does not exist)
Good but not a finite    NaN, ``Quality.BAD`` (a string, an array, a boolean, NaN...)
number
=======================  ===========================================================

A failure of the whole device (refused, timed out, session lost) raises
:class:`~gateway.errors.DeviceError`; no asyncua exception leaves this module.

Security. With a ``security`` section the adapter first asks the server for its endpoints
(the unauthenticated GetEndpoints service), picks the one with the configured policy and
mode, checks the server's certificate against ``server_certificate`` (if pinned) and
validates it against the trust store (time range, application URI, trusted, not revoked)
before it opens the secure channel; asyncua validates it again when the session is
created. The session then logs in with the user name and the password file's first line.

Recovery. asyncua's own auto-reconnect is off: when the session is lost, ``read`` raises
DeviceError (``connect`` or ``timeout``) so the gateway records a gap, and later calls to
``read`` reconnect by themselves (a new channel and session) with capped, jittered
exponential backoff; until a retry is due ``read`` raises at once without network traffic.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import random
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from asyncua import ua
from asyncua.client.client import Client
from asyncua.client.ua_client import UaClientState
from asyncua.common.utils import ServiceError
from asyncua.crypto import security_policies as sp
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.uacrypto import CertProperties
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from asyncua.ua.status_codes import StatusCodes
from asyncua.ua.uaerrors import UaStatusCodeError
from cryptography import x509
from cryptography.hazmat.primitives import serialization

from ...config.schema import MISSING
from ...errors import DeviceError
from ...wire.certs import (
    application_uri_of,
    certificate_from_bytes,
    describe_certificate,
    load_certificate_file,
    load_private_key_file,
)
from ..base import PointSpec, Quality, ReadResult
from .config import (
    OpcUaDeviceConfig,
    OpcUaPoint,
    OpcUaSecurity,
    parse_node_id,
    parse_plugin_device,
)

if TYPE_CHECKING:
    from ...config import DeviceConfig
    from ...config.schema import Section

__all__ = ["OpcUaInput", "create_input", "parse_device", "parse_point"]

_log = logging.getLogger("gateway.inputs.opcua")

POLICY_CLASSES: dict[str, type[sp.SecurityPolicy]] = {
    "Basic256Sha256": sp.SecurityPolicyBasic256Sha256,
    "Aes128_Sha256_RsaOaep": sp.SecurityPolicyAes128Sha256RsaOaep,
    "Aes256_Sha256_RsaPss": sp.SecurityPolicyAes256Sha256RsaPss,
}
MODES = {
    "Sign": ua.MessageSecurityMode.Sign,
    "SignAndEncrypt": ua.MessageSecurityMode.SignAndEncrypt,
}
# What the adapter checks of the server's certificate (key usage is left to the server's
# PKI: many plant servers' certificates lack nonRepudiation and would be refused).
SERVER_CERT_CHECKS = (
    CertificateValidatorOptions.TIME_RANGE
    | CertificateValidatorOptions.URI
    | CertificateValidatorOptions.TRUSTED
    | CertificateValidatorOptions.REVOKED
    | CertificateValidatorOptions.PEER_SERVER
)
_LOGIN_REFUSED = {"BadUserAccessDenied", "BadIdentityTokenRejected", "BadIdentityTokenInvalid",
                  "BadUserSignatureInvalid"}
_SESSION_LOST = {"BadSessionIdInvalid", "BadSessionClosed", "BadSessionNotActivated",
                 "BadSecureChannelIdInvalid", "BadSecureChannelClosed", "BadConnectionClosed",
                 "BadServerHalted", "BadShutdown", "BadCommunicationError", "BadNotConnected",
                 "BadServerNotConnected"}
RECONNECT_CAP_S = 10.0  # longest wait between reconnect attempts after a refusal/timeout
AUTH_RETRY_CAP_S = 60.0  # ... after a login/certificate refusal (do not lock the account)
SESSION_TIMEOUT_MS = 60_000  # a gateway that dies without closing frees its session soon


# ------------------------------------------------------------------ config plugin
# gateway.inputs.PROTOCOLS maps ``protocol: opcua`` to this module.


def parse_device(sec: Section) -> OpcUaDeviceConfig | Any:
    """Plugin hook: the device's OPC UA keys (endpoint, security, max_nodes_per_read)."""
    options = parse_plugin_device(sec)
    return MISSING if options is None else options


def parse_point(sec: Section, options: OpcUaDeviceConfig | None) -> OpcUaPoint | Any:
    """Plugin hook: a point's ``node`` (the core reads ``scale`` and ``offset``)."""
    node = sec.req("node", parse_node_id)
    return MISSING if node is MISSING else OpcUaPoint(node)


def create_input(device: DeviceConfig, points: Sequence[PointSpec], **_: Any) -> OpcUaInput:
    """Plugin hook: the adapter for one configured device."""
    options: OpcUaDeviceConfig = device.options
    cfg = dataclasses.replace(options, name=device.name,
                              poll_interval_s=device.poll_interval_s,
                              timeout_s=device.timeout_s)
    return OpcUaInput(cfg, points)


def _status_name(code: int) -> str:
    return str(ua.StatusCode(ua.UInt32(code)).name)


def _node_text(address: Any) -> str:
    if isinstance(address, OpcUaPoint):
        return address.node
    if isinstance(address, str):
        return address
    raise TypeError(f"an OPC UA point address must be an OpcUaPoint or a node id string, "
                    f"was {address!r}")


class OpcUaInput:
    """:class:`~gateway.inputs.base.DeviceInput` for one OPC UA server."""

    def __init__(self, config: OpcUaDeviceConfig, points: Sequence[PointSpec]) -> None:
        self.config = config
        self.name = config.name
        self.points = tuple(points)
        self._node_ids = [ua.NodeId.from_string(_node_text(p.address)) for p in self.points]
        self._scale = np.array([p.scale for p in self.points], dtype=np.float64)
        self._offset = np.array([p.offset for p in self.points], dtype=np.float64)
        self._client: Client | None = None
        self._read_index: list[int] = []  # point indexes read, in request order
        self._chunks: list[list[Any]] = []  # asyncua Node objects per Read call
        self._failures = 0
        self._retry_at = 0.0  # time.monotonic() before which read() does not reconnect
        self._last_error: DeviceError | None = None
        self._down = False
        self._status = np.zeros(len(self.points), dtype=np.uint32)  # last status per point

    # ------------------------------------------------------------------ DeviceInput

    @property
    def connected(self) -> bool:
        c = self._client
        return c is not None and c.uaclient.state is UaClientState.CONNECTED

    async def connect(self) -> None:
        """Open a session (dropping any old one); DeviceError on failure."""
        await self._drop()
        budget = 4 * self.config.timeout_s + 1.0
        try:
            async with asyncio.timeout(budget):
                self._client = await self._open()
        except Exception as exc:
            err = self._map(exc, "connecting")
            self._failed(err)
            raise err from None
        self._failures = 0
        self._retry_at = 0.0
        if self._down:
            _log.info("OPC UA device %s: connected again to %s", self.name, self.config.endpoint)
        self._down = False

    async def read(self) -> ReadResult:
        """Read every point once (one Read call); DeviceError if the device fails."""
        if not self.connected:
            if self._client is not None:  # the session died under us (server gone)
                await self._drop()
            if time.monotonic() < self._retry_at and self._last_error is not None:
                wait = self._retry_at - time.monotonic()
                last = str(self._last_error).removeprefix(f"device {self.name}: ")
                raise DeviceError(self.name, self._last_error.kind,
                                  f"{last} (next attempt in {wait:.1f} s)")
            await self.connect()
        client = self._client
        assert client is not None
        t = time.time()
        results: list[ua.DataValue] = []
        try:
            async with asyncio.timeout(self.config.timeout_s * max(1, len(self._chunks)) + 0.5):
                for chunk in self._chunks:
                    results.extend(await client.read_attributes(chunk))
        except Exception as exc:
            failure = self._map(exc, "reading")
            await self._drop()
            self._failed(failure, retry_now=True)
            raise failure from None
        if len(results) != len(self._read_index):
            bad = DeviceError(self.name, "protocol", f"the server answered {len(results)} "
                              f"values for {len(self._read_index)} nodes")
            await self._drop()
            self._failed(bad, retry_now=True)
            raise bad
        values, quality = self._convert(results)
        return ReadResult(t=t, values=values, quality=quality, requests=len(self._chunks))

    async def close(self) -> None:
        """Close the session; never raises."""
        await self._drop()

    async def __aenter__(self) -> OpcUaInput:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # ------------------------------------------------------------------ connecting

    async def _open(self) -> Client:
        cfg = self.config
        client = Client(cfg.endpoint, timeout=cfg.timeout_s,
                        watchdog_intervall=max(1.0, cfg.poll_interval_s))
        client.name = client.description = f"stiction-gateway ({self.name})"
        client.application_uri = "urn:stiction-gateway"
        client.session_timeout = SESSION_TIMEOUT_MS
        try:
            if cfg.security is not None:
                await self._secure(client, cfg.security)
            await client.connect()
            await self._prepare_nodes(client)
        except BaseException:
            await self._discard(client)
            raise
        return client

    async def _secure(self, client: Client, sec: OpcUaSecurity) -> None:
        try:
            cert = load_certificate_file(sec.certificate)
            key = load_private_key_file(sec.private_key)
            pinned = (load_certificate_file(sec.server_certificate)
                      if sec.server_certificate is not None else None)
            password = None
            if sec.password_file is not None:
                lines = sec.password_file.read_text(encoding="utf-8").splitlines()
                password = lines[0] if lines else ""
            trust = TrustStore([sec.trust_store], [])
            await trust.load()
        except (OSError, ValueError, TypeError) as exc:
            raise DeviceError(self.name, "auth", f"cannot load the security files: "
                              f"{exc}") from None
        client.application_uri = application_uri_of(cert) or client.application_uri
        policy = POLICY_CLASSES[sec.policy]
        mode = MODES[sec.mode]
        endpoint = await self._find_endpoint(policy.URI, mode, sec)
        try:
            server_cert = certificate_from_bytes(endpoint.ServerCertificate or b"")
        except ValueError:
            raise DeviceError(self.name, "auth", f"the server's {sec.policy}/{sec.mode} "
                              "endpoint carries no valid certificate") from None
        if pinned is not None and pinned != server_cert:
            raise DeviceError(self.name, "auth", f"the server presents certificate "
                              f"{describe_certificate(server_cert)}, not the one pinned in "
                              f"server_certificate ({describe_certificate(pinned)})")
        validator = CertificateValidator(SERVER_CERT_CHECKS, trust)
        try:
            await validator.validate(server_cert, endpoint.Server)
        except ServiceError as exc:
            raise DeviceError(self.name, "auth", self._cert_refusal(
                _status_name(exc.code), server_cert, endpoint.Server, sec)) from None
        key_pem = key.private_bytes(serialization.Encoding.PEM,
                                    serialization.PrivateFormat.PKCS8,
                                    serialization.NoEncryption())
        await client.set_security(
            policy,
            cert.public_bytes(serialization.Encoding.DER),
            CertProperties(key_pem, extension="pem"),
            server_certificate=server_cert.public_bytes(serialization.Encoding.DER),
            mode=mode,
        )
        client.certificate_validator = validator  # asyncua checks it again in CreateSession
        if sec.username is not None:
            client.set_user(sec.username)
            client.set_password(password or "")

    async def _find_endpoint(self, policy_uri: str, mode: ua.MessageSecurityMode,
                             sec: OpcUaSecurity) -> ua.EndpointDescription:
        probe = Client(self.config.endpoint, timeout=self.config.timeout_s)
        try:
            endpoints = await probe.connect_and_get_server_endpoints()
        finally:
            await self._discard(probe)
        for ep in endpoints:
            if ep.SecurityPolicyUri == policy_uri and ep.SecurityMode == mode:
                return ep
        offered = sorted({f"{ep.SecurityPolicyUri.rsplit('#', 1)[-1]}/{ep.SecurityMode.name}"
                          for ep in endpoints})
        raise DeviceError(self.name, "auth", f"the server offers no {sec.policy}/{sec.mode} "
                          f"endpoint (it offers: {', '.join(offered) or 'none'})")

    def _cert_refusal(self, status: str, cert: x509.Certificate,
                      server: ua.ApplicationDescription, sec: OpcUaSecurity) -> str:
        what = f"server certificate {describe_certificate(cert)}"
        if status == "BadCertificateUntrusted":
            return (f"{what} is not trusted ({status}): it is not in the trust store "
                    f"{sec.trust_store}; if this is the right server, copy its certificate "
                    f"there")
        if status == "BadCertificateTimeInvalid":
            return (f"{what} is not valid now ({status}): valid from "
                    f"{cert.not_valid_before_utc:%Y-%m-%d} to {cert.not_valid_after_utc:%Y-%m-%d}")
        if status == "BadCertificateUriInvalid":
            return (f"{what} does not name the server's application URI "
                    f"{server.ApplicationUri} ({status})")
        if status == "BadCertificateRevoked":
            return f"{what} is revoked ({status})"
        return f"{what} refused ({status})"

    async def _prepare_nodes(self, client: Client) -> None:
        """Resolve ``nsu=`` node ids against the server's namespace array and build the
        Read requests; points whose node cannot be resolved are left out (BAD)."""
        ids: list[ua.NodeId | None] = list(self._node_ids)
        uris = {n.NamespaceUri for n in self._node_ids
                if isinstance(n, ua.ExpandedNodeId) and n.NamespaceUri}
        if uris:
            namespaces = list(await client.get_namespace_array())
            for i, n in enumerate(self._node_ids):
                if isinstance(n, ua.ExpandedNodeId) and n.NamespaceUri:
                    if n.NamespaceUri in namespaces:
                        ids[i] = ua.NodeId(n.Identifier, ua.Int16(namespaces.index(n.NamespaceUri)),
                                           n.NodeIdType)
                    else:
                        ids[i] = None
                        _log.warning("OPC UA device %s: %s %s: the server has no namespace %s",
                                     self.name, self.points[i].loop, self.points[i].role,
                                     n.NamespaceUri)
        self._read_index = [i for i, n in enumerate(ids) if n is not None]
        nodes = [client.get_node(n) for n in ids if n is not None]
        size = self.config.max_nodes_per_read or max(1, len(nodes))
        self._chunks = [nodes[k:k + size] for k in range(0, len(nodes), size)]

    # ------------------------------------------------------------------ values

    def _convert(self, results: Sequence[ua.DataValue]) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.points)
        raw = np.full(n, np.nan)
        quality = np.full(n, Quality.BAD, dtype=np.uint8)
        status = np.full(n, StatusCodes.BadNodeIdUnknown, dtype=np.uint32)
        for i, dv in zip(self._read_index, results, strict=True):
            code = dv.StatusCode.value if dv.StatusCode is not None else 0
            status[i] = code
            if code & 0x80000000:  # Bad
                continue
            if code & 0x40000000:  # Uncertain: a gap, with its own quality
                quality[i] = Quality.UNCERTAIN
                continue
            value = dv.Value.Value if dv.Value is not None else None
            if isinstance(value, int | float | np.number) and not isinstance(value, bool):
                x = float(value)
                if np.isfinite(x):
                    raw[i] = x
                    quality[i] = Quality.GOOD
                    continue
            status[i] = StatusCodes.BadTypeMismatch  # for the log: not a usable number
        self._log_status_changes(status)
        values = raw * self._scale + self._offset
        values[quality != Quality.GOOD] = np.nan
        return values, quality

    def _log_status_changes(self, status: np.ndarray) -> None:
        changed = np.flatnonzero(status != self._status)
        for i in changed:
            p, code = self.points[i], int(status[i])
            if code & 0xC0000000:
                _log.warning("OPC UA device %s: loop %s %s (%s): %s", self.name, p.loop,
                             p.role, self._node_ids[i].to_string(), _status_name(code))
            elif self._status[i] & 0xC0000000:
                _log.info("OPC UA device %s: loop %s %s good again", self.name, p.loop, p.role)
        self._status = status

    # ------------------------------------------------------------------ failures

    def _map(self, exc: BaseException, doing: str) -> DeviceError:
        """One DeviceError for any exception asyncua or the network raised."""
        where = self.config.endpoint
        if isinstance(exc, DeviceError):
            return exc
        if isinstance(exc, TimeoutError):
            return DeviceError(self.name, "timeout", f"no answer from {where} within the "
                               f"timeout while {doing}")
        if isinstance(exc, ConnectionRefusedError):
            return DeviceError(self.name, "connect", f"{where} refused the connection")
        if isinstance(exc, UaStatusCodeError):
            name = _status_name(exc.code)
            sec = self.config.security
            if name in _LOGIN_REFUSED:
                if sec is not None and sec.username:
                    return DeviceError(self.name, "auth", f"login refused for user "
                                       f"{sec.username!r} ({name}): check security.username "
                                       f"and security.password_file")
                return DeviceError(self.name, "auth", f"the server refused an anonymous "
                                   f"session ({name}): configure security.username and "
                                   f"security.password_file")
            if name.startswith(("BadCertificate", "BadSecurity", "BadNoValidCertificates",
                                "BadApplicationSignatureInvalid")):
                mine = ""
                if sec is not None:
                    mine = (f": make the server trust the gateway's certificate "
                            f"{sec.certificate}")
                return DeviceError(self.name, "auth", f"the server refused the secure "
                                   f"channel or the gateway's certificate ({name}){mine}")
            if name in _SESSION_LOST:
                return DeviceError(self.name, "connect", f"session lost while {doing} ({name})")
            if name == "BadTooManyOperations":
                return DeviceError(self.name, "protocol", f"the server refuses to read "
                                   f"{len(self._read_index)} nodes in one call ({name}): set "
                                   f"max_nodes_per_read")
            return DeviceError(self.name, "protocol", f"error while {doing}: {name}")
        if isinstance(exc, ConnectionError | OSError):
            detail = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
            return DeviceError(self.name, "connect", f"connection to {where} failed while "
                               f"{doing}: {detail}")
        return DeviceError(self.name, "protocol", f"unexpected {type(exc).__name__} while "
                           f"{doing}: {exc}")

    def _failed(self, err: DeviceError, *, retry_now: bool = False) -> None:
        """Remember a failure: log once when the device goes down, schedule the retry."""
        self._last_error = err
        if retry_now:  # a running session broke: try again at the next poll
            self._failures = 0
            self._retry_at = 0.0
        else:
            self._failures += 1
            cap = AUTH_RETRY_CAP_S if err.kind == "auth" else RECONNECT_CAP_S
            delay = min(cap, 0.5 * 2.0 ** (self._failures - 1))
            self._retry_at = time.monotonic() + random.uniform(0.5, 1.0) * delay
        if not self._down:
            _log.warning("OPC UA %s", err)
            self._down = True
        else:
            _log.debug("OPC UA (still down) %s", err)

    async def _drop(self) -> None:
        client, self._client = self._client, None
        self._chunks = []
        self._read_index = []
        if client is not None:
            await self._discard(client)

    async def _discard(self, client: Client) -> None:
        """Close a client whatever its state, within the timeout; never raises."""
        try:
            async with asyncio.timeout(self.config.timeout_s):
                if client.uaclient.state is UaClientState.CONNECTED:
                    with contextlib.suppress(Exception):
                        await client.disconnect()
                else:  # dead link: stop asyncua's tasks without talking to the server
                    with contextlib.suppress(Exception):
                        await client.close_session()
        except TimeoutError:
            pass
        with contextlib.suppress(Exception):
            client.disconnect_socket()
