"""The simulated PLC's OPC UA face: an asyncua server serving each loop's OP and PV (and
its valve's position, ``L.POS``).

Each loop ``L`` is a folder object ``L`` under Objects with two Double variables,
``ns=2;s=L.OP`` (% of valve span) and ``ns=2;s=L.PV`` (process units), in the namespace
:data:`NAMESPACE_URI` (index 2, the first one a server registers). Before the first
:meth:`OpcUaPlcServer.update` they read ``BadWaitingForInitialData``; a NaN in an update is
served as ``BadNoCommunication`` (never a silent NaN with a good status).

Security is optional: without :class:`ServerSecurity` the server offers only
None/None with anonymous access. With it, it offers the given policies (default
Basic256Sha256 SignAndEncrypt), its certificate, and, when ``users`` is given, requires a
user name and password (anonymous sessions refused). ``trusted_clients`` (a directory of
client certificates) makes it refuse clients whose certificate is not there.

Usage (the plc-sim drives it once per simulation step)::

    async with OpcUaPlcServer(["FIC101", "LIC102"], port=4840) as server:
        out = bank.step()
        await server.update(out.op, out.pv)
"""

from __future__ import annotations

import dataclasses
import datetime
import hmac
import logging
import socket
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from asyncua import ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.crypto.truststore import TrustStore
from asyncua.crypto.validator import CertificateValidator, CertificateValidatorOptions
from asyncua.server.server import Server
from asyncua.server.user_managers import UserManager
from asyncua.ua.status_codes import StatusCodes
from numpy.typing import ArrayLike

from gateway.wire.certs import application_uri_of, load_certificate_file

__all__ = ["NAMESPACE_URI", "POLICY_TYPES", "OpcUaPlcServer", "ServerSecurity"]

_log = logging.getLogger("gateway.plcsim_opcua")

NAMESPACE_URI = "urn:stiction-gateway:plc-sim"
POLICY_TYPES: dict[tuple[str, str], ua.SecurityPolicyType] = {
    ("None", "None"): ua.SecurityPolicyType.NoSecurity,
    ("Basic256Sha256", "Sign"): ua.SecurityPolicyType.Basic256Sha256_Sign,
    ("Basic256Sha256", "SignAndEncrypt"): ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
    ("Aes128_Sha256_RsaOaep", "Sign"): ua.SecurityPolicyType.Aes128Sha256RsaOaep_Sign,
    ("Aes128_Sha256_RsaOaep", "SignAndEncrypt"):
        ua.SecurityPolicyType.Aes128Sha256RsaOaep_SignAndEncrypt,
    ("Aes256_Sha256_RsaPss", "Sign"): ua.SecurityPolicyType.Aes256Sha256RsaPss_Sign,
    ("Aes256_Sha256_RsaPss", "SignAndEncrypt"):
        ua.SecurityPolicyType.Aes256Sha256RsaPss_SignAndEncrypt,
}


@dataclasses.dataclass(frozen=True)
class ServerSecurity:
    """Certificate (DER or PEM) and private key of the server; the (policy, mode) pairs it
    offers; ``users`` maps user name to password (None: anonymous sessions allowed);
    ``trusted_clients`` a directory of client certificates to accept (None: any)."""

    certificate: Path
    private_key: Path
    policies: tuple[tuple[str, str], ...] = (("Basic256Sha256", "SignAndEncrypt"),)
    users: Mapping[str, str] | None = None
    trusted_clients: Path | None = None

    def __post_init__(self) -> None:
        for pair in self.policies:
            if tuple(pair) not in POLICY_TYPES:
                known = ", ".join("/".join(k) for k in POLICY_TYPES)
                raise ValueError(f"policies: unknown policy/mode {pair!r} (known: {known})")


class _UserMap(UserManager):
    """asyncua user manager: a fixed user name -> password map (constant-time compare)."""

    def __init__(self, users: Mapping[str, str]) -> None:
        self._users = {u: p.encode() for u, p in users.items()}

    def get_user(self, iserver: Any, username: str | None = None, password: str | None = None,
                 certificate: Any = None) -> User | None:
        expected = self._users.get(username or "")
        if expected is None or password is None:
            return None
        if not hmac.compare_digest(expected, password.encode()):
            return None
        return User(role=UserRole.User, name=username)


class OpcUaPlcServer:
    """An OPC UA server for ``loops`` (names, in the order of the arrays given to
    :meth:`update`), bound to ``host:port``. :meth:`start` / :meth:`stop` may be repeated
    (a restart serves the last values again)."""

    def __init__(
        self,
        loops: Sequence[str],
        *,
        host: str = "127.0.0.1",
        port: int = 4840,
        security: ServerSecurity | None = None,
        application_uri: str | None = None,
        name: str = "stiction-gateway plc-sim",
        clock: bool = True,
    ) -> None:
        if len(set(loops)) != len(loops):
            raise ValueError("loops: names must be unique")
        if not 0 <= port < 65536:
            raise ValueError(f"port must be in 0..65535 (0: a free port), was {port}")
        self.loops = tuple(loops)
        self.host = host
        self.port = port
        self.security = security
        self.name = name
        self.clock = clock  # False: no CurrentTime updates, so stop() need not wait up to 1 s
        if application_uri is None and security is not None:
            application_uri = application_uri_of(load_certificate_file(security.certificate))
        self.application_uri = application_uri or "urn:stiction-gateway:plc-sim:server"
        self._server: Server | None = None
        self._nodes: list[tuple[ua.NodeId, ...]] = []
        self._last: tuple[np.ndarray, ...] | None = None
        self.namespace_index = 2

    @property
    def endpoint(self) -> str:
        return f"opc.tcp://{self.host}:{self.port}"

    @property
    def server(self) -> Server | None:
        """The underlying asyncua server while running (for tests and extensions)."""
        return self._server

    def node_id(self, loop: str, role: str) -> str:
        """The node id string of a loop's ``op`` or ``pv`` variable."""
        return f"ns={self.namespace_index};s={loop}.{role.upper()}"

    async def start(self) -> None:
        if self._server is not None:
            return
        if self.port == 0:  # pick a free port once; a restart keeps it
            with socket.socket() as sock:
                sock.bind((self.host, 0))
                self.port = int(sock.getsockname()[1])
        server = Server(user_manager=_UserMap(self.security.users)
                        if self.security is not None and self.security.users else None)
        await server.init()
        server.disable_clock(not self.clock)
        server.set_endpoint(self.endpoint)
        server.set_server_name(self.name)
        await server.set_application_uri(self.application_uri)
        sec = self.security
        if sec is None:
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
            server.set_identity_tokens([ua.AnonymousIdentityToken])
        else:
            await server.load_certificate(str(sec.certificate),
                                          format=_format_of(sec.certificate))
            await server.load_private_key(str(sec.private_key),
                                          format=_format_of(sec.private_key))
            server.set_security_policy([POLICY_TYPES[tuple(p)] for p in sec.policies])  # type: ignore[index]
            server.set_identity_tokens([ua.UserNameIdentityToken] if sec.users
                                       else [ua.AnonymousIdentityToken])
            if sec.trusted_clients is not None:
                trust = TrustStore([sec.trusted_clients], [])
                await trust.load()
                server.set_certificate_validator(CertificateValidator(
                    CertificateValidatorOptions.TIME_RANGE
                    | CertificateValidatorOptions.TRUSTED
                    | CertificateValidatorOptions.PEER_CLIENT, trust))
        idx = await server.register_namespace(NAMESPACE_URI)
        self.namespace_index = int(idx)
        objects = server.nodes.objects
        self._nodes = []
        initial = ua.DataValue(ua.Variant(float("nan"), ua.VariantType.Double),
                               StatusCode=ua.StatusCode(ua.UInt32(StatusCodes.BadWaitingForInitialData)))
        for loop in self.loops:
            folder = await objects.add_folder(ua.NodeId.from_string(f"ns={idx};s={loop}"), loop)
            pair = []
            for role in ("OP", "PV", "POS"):
                nid = ua.NodeId.from_string(f"ns={idx};s={loop}.{role}")
                await folder.add_variable(nid, f"{loop}.{role}",
                                          ua.Variant(0.0, ua.VariantType.Double))
                await server.write_attribute_value(nid, initial)
                pair.append(nid)
            self._nodes.append(tuple(pair))
        await server.start()
        self._server = server
        if self._last is not None:
            await self.update(*self._last)
        _log.info("OPC UA plc-sim serving %d loops on %s", len(self.loops), self.endpoint)

    async def update(self, op: ArrayLike, pv: ArrayLike, position: ArrayLike | None = None
                     ) -> None:
        """Publish one sample of every loop (arrays in the order of ``loops``): OP, PV and
        the valve's position (``L.POS``; None or NaN: bad, no communication)."""
        op_a = np.asarray(op, dtype=np.float64).reshape(-1)
        pv_a = np.asarray(pv, dtype=np.float64).reshape(-1)
        pos_a = (np.full(op_a.shape, np.nan) if position is None
                 else np.asarray(position, dtype=np.float64).reshape(-1))
        if op_a.shape != (len(self.loops),) or pv_a.shape != (len(self.loops),) \
                or pos_a.shape != op_a.shape:
            raise ValueError(f"op, pv and position must have {len(self.loops)} values, had "
                             f"{op_a.size}, {pv_a.size} and {pos_a.size}")
        self._last = (op_a.copy(), pv_a.copy(), pos_a.copy())
        server = self._server
        if server is None:
            return
        now = datetime.datetime.now(datetime.UTC)
        for nodes, *values in zip(self._nodes, op_a, pv_a, pos_a, strict=True):
            for nid, x in zip(nodes, values, strict=True):
                await server.write_attribute_value(nid, _datavalue(float(x), now))

    async def stop(self) -> None:
        server, self._server = self._server, None
        if server is not None:
            await server.stop()

    async def __aenter__(self) -> OpcUaPlcServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()


def _format_of(path: Path) -> str:
    return "pem" if path.read_bytes().lstrip().startswith(b"-----BEGIN") else "der"


def _datavalue(x: float, now: datetime.datetime) -> ua.DataValue:
    status = StatusCodes.Good if np.isfinite(x) else StatusCodes.BadNoCommunication
    return ua.DataValue(ua.Variant(x, ua.VariantType.Double),
                        StatusCode=ua.StatusCode(ua.UInt32(status)),
                        SourceTimestamp=now, ServerTimestamp=now)  # type: ignore[arg-type]
