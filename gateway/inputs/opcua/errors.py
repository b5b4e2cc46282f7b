"""asyncua and network exceptions mapped to :class:`~gateway.errors.DeviceError`, with a
message that says what to check (the login, the trust store, max_nodes_per_read...)."""

from __future__ import annotations

from asyncua import ua
from asyncua.ua.uaerrors import UaStatusCodeError

from ...errors import DeviceError
from .config import OpcUaSecurity

__all__ = ["map_error", "status_name"]

_LOGIN_REFUSED = {"BadUserAccessDenied", "BadIdentityTokenRejected", "BadIdentityTokenInvalid",
                  "BadUserSignatureInvalid"}
_SESSION_LOST = {"BadSessionIdInvalid", "BadSessionClosed", "BadSessionNotActivated",
                 "BadSecureChannelIdInvalid", "BadSecureChannelClosed", "BadConnectionClosed",
                 "BadServerHalted", "BadShutdown", "BadCommunicationError", "BadNotConnected",
                 "BadServerNotConnected"}


def status_name(code: int) -> str:
    return str(ua.StatusCode(ua.UInt32(code)).name)


def map_error(exc: BaseException, *, device: str, endpoint: str, doing: str,
              security: OpcUaSecurity | None, nodes: int) -> DeviceError:
    """One DeviceError for any exception asyncua or the network raised while ``doing``."""
    if isinstance(exc, DeviceError):
        return exc
    if isinstance(exc, TimeoutError):
        return DeviceError(device, "timeout", f"no answer from {endpoint} within the "
                           f"timeout while {doing}")
    if isinstance(exc, ConnectionRefusedError):
        return DeviceError(device, "connect", f"{endpoint} refused the connection")
    if isinstance(exc, UaStatusCodeError):
        return _status_error(status_name(exc.code), device=device, doing=doing,
                             security=security, nodes=nodes)
    if isinstance(exc, ConnectionError | OSError):
        detail = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        return DeviceError(device, "connect", f"connection to {endpoint} failed while "
                           f"{doing}: {detail}")
    return DeviceError(device, "protocol", f"unexpected {type(exc).__name__} while "
                       f"{doing}: {exc}")


def _status_error(name: str, *, device: str, doing: str, security: OpcUaSecurity | None,
                  nodes: int) -> DeviceError:
    if name in _LOGIN_REFUSED:
        if security is not None and security.username:
            return DeviceError(device, "auth", f"login refused for user "
                               f"{security.username!r} ({name}): check security.username "
                               f"and security.password_file")
        return DeviceError(device, "auth", f"the server refused an anonymous session "
                           f"({name}): configure security.username and "
                           f"security.password_file")
    if name.startswith(("BadCertificate", "BadSecurity", "BadNoValidCertificates",
                        "BadApplicationSignatureInvalid")):
        if name == "BadCertificateTimeInvalid":
            mine = (f": the gateway's certificate {security.certificate} has expired or is "
                    "not valid yet; make a new one (stiction-gateway opcua-cert) and have "
                    "the server trust it" if security is not None else "")
            return DeviceError(device, "auth", f"the server refused the gateway's "
                               f"certificate ({name}){mine}",
                               reason="gateway certificate expired")
        mine = ""
        if security is not None:
            mine = (f": make the server trust the gateway's certificate "
                    f"{security.certificate}")
        return DeviceError(device, "auth", f"the server refused the secure channel or the "
                           f"gateway's certificate ({name}){mine}",
                           reason="gateway certificate rejected")
    if name in _SESSION_LOST:
        return DeviceError(device, "connect", f"session lost while {doing} ({name})")
    if name == "BadTooManyOperations":
        return DeviceError(device, "protocol", f"the server refuses to read {nodes} nodes in "
                           f"one call ({name}): set max_nodes_per_read")
    return DeviceError(device, "protocol", f"error while {doing}: {name}")
