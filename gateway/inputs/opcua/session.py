"""Opening and closing asyncua sessions, secured as configured.

With a ``security`` section the server's endpoints are asked for first (the unauthenticated
GetEndpoints service); the one with the configured policy and mode is picked, the server's
certificate is checked against ``server_certificate`` (if pinned) and validated against the
trust store (time range, application URI, trusted, not revoked) before the secure channel
is opened; asyncua validates it again when the session is created. The session then logs in
with the user name and the password file's first line.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime

from asyncua import ua
from asyncua.client.client import Client
from asyncua.client.ua_client import UaClientState
from asyncua.common.utils import ServiceError
from asyncua.crypto import security_policies as sp
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.uacrypto import CertProperties
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from cryptography import x509
from cryptography.hazmat.primitives import serialization

from ...errors import DeviceError
from ...wire.certs import (
    application_uri_of,
    certificate_from_bytes,
    describe_certificate,
    load_certificate_file,
    load_private_key_file,
)
from .config import OpcUaDeviceConfig, OpcUaSecurity
from .errors import status_name

__all__ = ["SERVER_CERT_REASONS", "discard", "new_client", "secure", "server_cert_reason"]

POLICY_CLASSES: dict[str, type[sp.SecurityPolicy]] = {
    "Basic256Sha256": sp.SecurityPolicyBasic256Sha256,
    "Aes128_Sha256_RsaOaep": sp.SecurityPolicyAes128Sha256RsaOaep,
    "Aes256_Sha256_RsaPss": sp.SecurityPolicyAes256Sha256RsaPss,
}
MODES = {
    "Sign": ua.MessageSecurityMode.Sign,
    "SignAndEncrypt": ua.MessageSecurityMode.SignAndEncrypt,
}
# What the source checks of the server's certificate (key usage is left to the server's
# PKI: many plant servers' certificates lack nonRepudiation and would be refused).
SERVER_CERT_CHECKS = (
    CertificateValidatorOptions.TIME_RANGE
    | CertificateValidatorOptions.URI
    | CertificateValidatorOptions.TRUSTED
    | CertificateValidatorOptions.REVOKED
    | CertificateValidatorOptions.PEER_SERVER
)
SERVER_CERT_REASONS = {
    "BadCertificateUntrusted": "server certificate untrusted",
    "BadCertificateUriInvalid": "server certificate URI mismatch",
    "BadCertificateRevoked": "server certificate revoked",
    "BadCertificateRevocationUnknown": "server certificate revocation unknown",
    "BadCertificateHostNameInvalid": "server certificate host name mismatch",
    "BadCertificateUseNotAllowed": "server certificate use not allowed",
    "BadCertificateInvalid": "server certificate invalid",
}
"""``stiction_device_down_reason`` for a server certificate the gateway's trust store
refuses, by status (an expired one: :func:`server_cert_reason`)."""
SESSION_TIMEOUT_MS = 60_000  # a gateway that dies without closing frees its session soon


def new_client(cfg: OpcUaDeviceConfig) -> Client:
    """A client for ``cfg`` (not connected; asyncua's own reconnecting stays off)."""
    client = Client(cfg.endpoint, timeout=cfg.timeout_s,
                    watchdog_intervall=max(1.0, cfg.poll_interval_s))
    client.name = client.description = f"stiction-gateway ({cfg.name})"
    client.application_uri = "urn:stiction-gateway"
    client.session_timeout = SESSION_TIMEOUT_MS
    return client


async def secure(client: Client, cfg: OpcUaDeviceConfig, sec: OpcUaSecurity) -> None:
    """Set up ``client``'s security, certificate and login as ``sec`` says."""
    name = cfg.name
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
        raise DeviceError(name, "auth", f"cannot load the security files: {exc}",
                          reason="security files unreadable") from None
    client.application_uri = application_uri_of(cert) or client.application_uri
    policy = POLICY_CLASSES[sec.policy]
    mode = MODES[sec.mode]
    endpoint = await _find_endpoint(cfg, policy.URI, mode, sec)
    try:
        server_cert = certificate_from_bytes(endpoint.ServerCertificate or b"")
    except ValueError:
        raise DeviceError(name, "auth", f"the server's {sec.policy}/{sec.mode} endpoint "
                          "carries no valid certificate",
                          reason="server certificate invalid") from None
    if pinned is not None and pinned != server_cert:
        raise DeviceError(name, "auth", f"the server presents certificate "
                          f"{describe_certificate(server_cert)}, not the one pinned in "
                          f"server_certificate ({describe_certificate(pinned)})",
                          reason="server certificate not the pinned one")
    validator = CertificateValidator(SERVER_CERT_CHECKS, trust)
    try:
        await validator.validate(server_cert, endpoint.Server)
    except ServiceError as exc:
        status = status_name(exc.code)
        raise DeviceError(name, "auth", _cert_refusal(status, server_cert, endpoint.Server,
                                                      sec),
                          reason=server_cert_reason(status, server_cert)) from None
    key_pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
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


async def _find_endpoint(cfg: OpcUaDeviceConfig, policy_uri: str,
                         mode: ua.MessageSecurityMode, sec: OpcUaSecurity
                         ) -> ua.EndpointDescription:
    probe = Client(cfg.endpoint, timeout=cfg.timeout_s)
    try:
        endpoints = await probe.connect_and_get_server_endpoints()
    finally:
        await discard(probe, cfg.timeout_s)
    for ep in endpoints:
        if ep.SecurityPolicyUri == policy_uri and ep.SecurityMode == mode:
            return ep
    offered = sorted({f"{ep.SecurityPolicyUri.rsplit('#', 1)[-1]}/{ep.SecurityMode.name}"
                      for ep in endpoints})
    raise DeviceError(cfg.name, "auth", f"the server offers no {sec.policy}/{sec.mode} "
                      f"endpoint (it offers: {', '.join(offered) or 'none'})",
                      reason="no matching endpoint")


def server_cert_reason(status: str, cert: x509.Certificate,
                       now: datetime.datetime | None = None) -> str:
    """The few words of ``stiction_device_down_reason`` for a server certificate the
    gateway refused with ``status`` (our trust store's verdict)."""
    if status == "BadCertificateTimeInvalid":
        now = now or datetime.datetime.now(datetime.UTC)
        if now < cert.not_valid_before_utc:
            return "server certificate not yet valid"
        return "server certificate expired"
    return SERVER_CERT_REASONS.get(status, "server certificate refused")


def _cert_refusal(status: str, cert: x509.Certificate, server: ua.ApplicationDescription,
                  sec: OpcUaSecurity) -> str:
    what = f"server certificate {describe_certificate(cert)}"
    if status == "BadCertificateUntrusted":
        return (f"{what} is not trusted ({status}): it is not in the trust store "
                f"{sec.trust_store}; if this is the right server, copy its certificate there")
    if status == "BadCertificateTimeInvalid":
        now = datetime.datetime.now(datetime.UTC)
        state = ("expired" if now > cert.not_valid_after_utc else "not yet valid"
                 if now < cert.not_valid_before_utc else "not valid now")
        return (f"{what} is {state} ({status}): valid from "
                f"{cert.not_valid_before_utc:%Y-%m-%d %H:%M} to "
                f"{cert.not_valid_after_utc:%Y-%m-%d %H:%M} UTC; the server needs a new "
                f"certificate (and the trust store {sec.trust_store} its copy), or this "
                f"machine's clock is wrong")
    if status == "BadCertificateUriInvalid":
        return (f"{what} does not name the server's application URI "
                f"{server.ApplicationUri} ({status})")
    if status == "BadCertificateRevoked":
        return f"{what} is revoked ({status})"
    return f"{what} refused ({status})"


async def discard(client: Client, timeout_s: float) -> None:
    """Close a client whatever its state, within ``timeout_s``; never raises."""
    try:
        async with asyncio.timeout(timeout_s):
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
