"""A private certificate authority and one certificate per node, for zenoh's mutual TLS.

Every guidebelt node proves who it is with a certificate signed by the deployment's own CA,
and the daemon's zenoh access control grants rights by the certificate's common name
(``protocol.access``). Nothing here talks to the network: ``guidebelt certs`` calls it once
at installation, the tests call it into a temporary folder.

Keys are ECDSA P-256 (small, fast to verify on the wearable, accepted by zenoh's rustls);
files are PEM, private keys PKCS#8 unencrypted (zenoh reads no passphrase) and written with
mode 0600 from the start, never world-readable even for an instant.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

CA_STEM = "ca"
DEFAULT_DAYS = 825
"""A leaf's life: the longest that common TLS clients accept; renew with ``guidebelt certs``."""
CA_DAYS = 3650


@dataclass(frozen=True)
class KeyPair:
    """A certificate and its private key on disk."""

    certificate: Path
    private_key: Path


def _write_private(path: Path, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.chmod(path, 0o600)  # an existing file keeps its old mode through O_CREAT


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> None:
    _write_private(
        path,
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        ),
    )


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "guidebelt"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def make_ca(directory: Path, name: str = "guidebelt CA", days: int = CA_DAYS) -> KeyPair:
    """A new self-signed CA in ``directory`` (``ca.pem``, ``ca.key``)."""
    directory.mkdir(parents=True, exist_ok=True)
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    subject = _name(name)
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        # path_length 0: the CA signs nodes, never another CA.
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), False)
        .sign(key, hashes.SHA256())
    )
    pair = KeyPair(directory / f"{CA_STEM}.pem", directory / f"{CA_STEM}.key")
    _write_key(pair.private_key, key)
    pair.certificate.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return pair


def load_ca(directory: Path) -> KeyPair:
    pair = KeyPair(directory / f"{CA_STEM}.pem", directory / f"{CA_STEM}.key")
    for path in (pair.certificate, pair.private_key):
        if not path.is_file():
            raise FileNotFoundError(f"no CA in {directory}: {path.name} missing")
    return pair


def _san(hosts: tuple[str, ...]) -> list[x509.GeneralName]:
    names: list[x509.GeneralName] = []
    for host in hosts:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return names


def issue(
    ca: KeyPair,
    common_name: str,
    directory: Path,
    stem: str,
    hosts: tuple[str, ...] = ("localhost", "127.0.0.1"),
    days: int = DEFAULT_DAYS,
) -> KeyPair:
    """A certificate for ``common_name`` signed by ``ca``, as ``<stem>.pem`` / ``<stem>.key``.

    ``hosts`` go in the subject alternative names: a node that listens must carry the names
    its peers dial (zenoh checks them on connect); for one that only connects they are
    harmless. Both server and client use are allowed, since a zenoh peer may do either.
    """
    ca_key = serialization.load_pem_private_key(ca.private_key.read_bytes(), password=None)
    ca_cert = x509.load_pem_x509_certificate(ca.certificate.read_bytes())
    if not isinstance(ca_key, ec.EllipticCurvePrivateKey):
        raise ValueError(f"{ca.private_key}: not an EC key made by guidebelt certs")
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), False
        )
    )
    if hosts:
        builder = builder.add_extension(x509.SubjectAlternativeName(_san(hosts)), False)
    cert = builder.sign(ca_key, hashes.SHA256())
    directory.mkdir(parents=True, exist_ok=True)
    pair = KeyPair(directory / f"{stem}.pem", directory / f"{stem}.key")
    _write_key(pair.private_key, key)
    pair.certificate.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return pair


def common_name_of(certificate: Path) -> str:
    cert = x509.load_pem_x509_certificate(certificate.read_bytes())
    return str(cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value)
