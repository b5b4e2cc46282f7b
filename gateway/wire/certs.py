"""OPC UA application instance certificates: create them, and read the ones a config names.

``make_certificate`` writes a self-signed certificate (DER) and its RSA-2048 private key
(PEM, PKCS#8, mode 0600) fit for OPC UA: the application URI and host names as
subjectAltName, key usage as OPC UA Part 6 asks, extended key usage clientAuth (or
serverAuth for a server). ``main`` is the ``stiction-gateway opcua-cert`` command.

The loaders accept DER or PEM whatever the file is called, so a ``.crt`` or ``.cer`` file
from a plant's PKI works as well as asyncua's ``.der``/``.pem`` convention.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import ipaddress
import os
import socket
import sys
from collections.abc import Sequence
from pathlib import Path

from asyncua.crypto import cert_gen
from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

__all__ = [
    "application_uri_of",
    "describe_certificate",
    "load_certificate_file",
    "load_private_key_file",
    "main",
    "make_certificate",
    "thumbprint",
]


def load_certificate_file(path: str | os.PathLike[str]) -> x509.Certificate:
    """An X.509 certificate from a DER or PEM file. Raises OSError or ValueError."""
    data = Path(path).read_bytes()
    return certificate_from_bytes(data)


def certificate_from_bytes(data: bytes) -> x509.Certificate:
    """An X.509 certificate from DER or PEM bytes (the first one of a DER chain)."""
    if data.lstrip().startswith(b"-----BEGIN"):
        return x509.load_pem_x509_certificate(data)
    return x509.load_der_x509_certificate(_first_der(data))


def _first_der(data: bytes) -> bytes:
    """The first DER element of ``data`` (OPC UA servers may send a chain of certificates
    concatenated); ``data`` itself when it cannot be parsed as a DER length."""
    if len(data) < 2 or data[0] != 0x30:
        return data
    first = data[1]
    if first < 0x80:
        end = 2 + first
    else:
        n = first & 0x7F
        if n == 0 or n > 4 or len(data) < 2 + n:
            return data
        end = 2 + n + int.from_bytes(data[2 : 2 + n], "big")
    return data[:end] if end <= len(data) else data


def load_private_key_file(path: str | os.PathLike[str]) -> rsa.RSAPrivateKey:
    """An unencrypted RSA private key from a PEM or DER file. Raises OSError, ValueError
    (not a key, or encrypted) or TypeError (not RSA)."""
    data = Path(path).read_bytes()
    if data.lstrip().startswith(b"-----BEGIN"):
        key = serialization.load_pem_private_key(data, password=None)
    else:
        key = serialization.load_der_private_key(data, password=None)
    if not isinstance(key, rsa.RSAPrivateKey):
        raise TypeError(f"is a {type(key).__name__}, OPC UA needs an RSA key")
    return key


def application_uri_of(cert: x509.Certificate) -> str | None:
    """The first URI in the certificate's subjectAltName (the OPC UA application URI)."""
    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName)
    except x509.ExtensionNotFound:
        return None
    uris = san.value.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else None


def thumbprint(cert: x509.Certificate) -> str:
    """SHA-1 thumbprint as OPC UA tools show it (hex, upper case)."""
    return hashlib.sha1(cert.public_bytes(serialization.Encoding.DER)).hexdigest().upper()


def describe_certificate(cert: x509.Certificate) -> str:
    """``CN=..., thumbprint ...`` for log and error messages."""
    cns = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    cn = str(cns[0].value) if cns else cert.subject.rfc4514_string()
    return f"CN={cn}, SHA-1 thumbprint {thumbprint(cert)}"


def make_certificate(
    cert_path: str | os.PathLike[str],
    key_path: str | os.PathLike[str],
    *,
    common_name: str,
    application_uri: str,
    hostnames: Sequence[str],
    days: int = 730,
    server: bool = False,
    overwrite: bool = False,
) -> x509.Certificate:
    """Write a self-signed OPC UA application certificate (DER) and its key (PEM, 0600).

    ``hostnames`` go into subjectAltName as DNS names (IP addresses as IP entries);
    ``application_uri`` as the URI entry, which must equal the application URI the
    client or server announces. ``server`` selects serverAuth instead of clientAuth.
    Refuses to replace existing files unless ``overwrite``.
    """
    if not application_uri:
        raise ValueError("application_uri must not be empty")
    if days < 1:
        raise ValueError(f"days must be >= 1, was {days}")
    cert_file, key_file = Path(cert_path), Path(key_path)
    if not overwrite:
        for f in (cert_file, key_file):
            if f.exists():
                raise FileExistsError(f"{f} exists (use overwrite to replace it)")
    names: list[x509.GeneralName] = [x509.UniformResourceIdentifier(application_uri)]
    for host in hostnames:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    key = cert_gen.generate_private_key()
    cert = cert_gen.generate_self_signed_app_certificate(
        key, common_name, {}, names, [usage], days=days
    )
    cert_file.parent.mkdir(parents=True, exist_ok=True)
    key_file.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(key_file, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(cert_gen.dump_private_key_as_pem(key))
    os.chmod(key_file, 0o600)
    cert_file.write_bytes(cert.public_bytes(serialization.Encoding.DER))
    return cert


def build_parser() -> argparse.ArgumentParser:
    host = socket.gethostname()
    p = argparse.ArgumentParser(
        prog="stiction-gateway opcua-cert",
        description="Create a self-signed OPC UA application certificate and private key.",
    )
    p.add_argument("--cert", default="pki/client.der", help="certificate file, DER "
                   "(default: %(default)s)")
    p.add_argument("--key", default="pki/client.pem", help="private key file, PEM "
                   "(default: %(default)s)")
    p.add_argument("--name", default="stiction-gateway", help="common name (default: "
                   "%(default)s)")
    p.add_argument("--uri", default=f"urn:{host}:stiction-gateway",
                   help="application URI, put in subjectAltName (default: %(default)s)")
    p.add_argument("--host", action="append", dest="hosts", metavar="NAME",
                   help=f"DNS name or IP address for subjectAltName, repeatable "
                   f"(default: {host})")
    p.add_argument("--days", type=int, default=730, help="validity in days (default: "
                   "%(default)s)")
    p.add_argument("--server", action="store_true",
                   help="a server certificate (serverAuth), e.g. for the simulated PLC")
    p.add_argument("--force", action="store_true", help="replace existing files")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """``stiction-gateway opcua-cert``: returns the process exit code."""
    args = build_parser().parse_args(argv)
    try:
        cert = make_certificate(
            args.cert, args.key, common_name=args.name, application_uri=args.uri,
            hostnames=args.hosts or [socket.gethostname()], days=args.days,
            server=args.server, overwrite=args.force,
        )
    except FileExistsError as exc:
        print(f"opcua-cert: {exc.args[0].replace('use overwrite', 'use --force')}",
              file=sys.stderr)
        return 1
    except (OSError, ValueError) as exc:
        print(f"opcua-cert: {exc}", file=sys.stderr)
        return 1
    until = cert.not_valid_after_utc.astimezone(datetime.UTC).date().isoformat()
    print(f"certificate: {args.cert} ({describe_certificate(cert)}, valid until {until})")
    print(f"private key: {args.key} (keep it secret: mode 0600)")
    print(f"application URI: {args.uri}")
    if not args.server:
        print("Next: make the OPC UA server trust this certificate (copy the .der file into "
              "its trusted-clients folder or accept it in its certificate manager), and put "
              "the server's certificate into the gateway's trust_store directory.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
