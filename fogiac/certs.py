"""Certificates for the stack's mutual TLS: one CA, a server and client certificates.

AWS Client VPN requires RSA 2048 keys, so everything here is RSA 2048 for one code path.
The relay (edge and cloud ends) and the Client VPN endpoint trust the same CA. Private keys are
written 0600 and never printed; callers that put them into Pulumi mark them secret.
"""

from __future__ import annotations

import datetime as _dt
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from fogiac.plan.model import server_name
from fogiac.state import write_atomic

_VALID_DAYS = 825


@dataclass(frozen=True)
class KeyPair:
    """A PEM certificate and its PEM (PKCS#8, unencrypted) private key."""

    cert_pem: bytes
    key_pem: bytes

    @property
    def common_name(self) -> str:
        cert = x509.load_pem_x509_certificate(self.cert_pem)
        return cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value  # type: ignore[return-value]


@dataclass(frozen=True)
class Bundle:
    """What a stack needs: the CA, a server certificate and a client certificate."""

    ca: KeyPair
    server: KeyPair
    client: KeyPair


def _new_key() -> rsa.RSAPrivateKey:
    return rsa.generate_private_key(public_exponent=65537, key_size=2048)


def _key_pem(key: rsa.RSAPrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def new_ca(common_name: str) -> KeyPair:
    key = _new_key()
    now = _dt.datetime.now(_dt.timezone.utc)
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(_name(common_name))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - _dt.timedelta(minutes=5))
        .not_valid_after(now + _dt.timedelta(days=_VALID_DAYS))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True, content_commitment=False, key_encipherment=False,
                data_encipherment=False, key_agreement=False, key_cert_sign=True, crl_sign=True,
                encipher_only=False, decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return KeyPair(cert.public_bytes(serialization.Encoding.PEM), _key_pem(key))


def issue(
    ca: KeyPair,
    common_name: str,
    *,
    server: bool,
    dns_names: tuple[str, ...] = (),
    ip_addresses: tuple[str, ...] = (),
) -> KeyPair:
    """Issue a leaf certificate signed by ``ca``; server ones carry serverAuth, others clientAuth.

    AWS ACM only imports a server certificate whose subject has a domain name, so callers give
    server certificates a DNS-style common name and repeat it in ``dns_names``.
    """
    ca_cert = x509.load_pem_x509_certificate(ca.cert_pem)
    ca_key = serialization.load_pem_private_key(ca.key_pem, password=None)
    key = _new_key()
    now = _dt.datetime.now(_dt.timezone.utc)
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - _dt.timedelta(minutes=5))
        .not_valid_after(now + _dt.timedelta(days=_VALID_DAYS))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True, content_commitment=False, key_encipherment=True,
                data_encipherment=False, key_agreement=False, key_cert_sign=False, crl_sign=False,
                encipher_only=False, decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_cert.public_key()),  # type: ignore[arg-type]
            critical=False,
        )
    )
    alt_names: list[x509.GeneralName] = [x509.DNSName(n) for n in dns_names]
    alt_names += [x509.IPAddress(ipaddress.ip_address(a)) for a in ip_addresses]
    if alt_names:
        builder = builder.add_extension(x509.SubjectAlternativeName(alt_names), critical=False)
    cert = builder.sign(ca_key, hashes.SHA256())  # type: ignore[arg-type]
    return KeyPair(cert.public_bytes(serialization.Encoding.PEM), _key_pem(key))


def new_bundle(stack: str) -> Bundle:
    ca = new_ca(f"fogiac CA {stack}")
    name = server_name(stack)
    return Bundle(
        ca=ca,
        server=issue(ca, name, server=True, dns_names=(name,)),
        client=issue(ca, f"client.{stack}.fogiac", server=False),
    )


def write_private(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` with mode 0600 from the first byte (never world-readable)."""
    write_atomic(path, data, mode=0o600)


_FILES = {
    "ca": ("ca.pem", "ca.key"),
    "server": ("server.pem", "server.key"),
    "client": ("client.pem", "client.key"),
}


def save_bundle(bundle: Bundle, directory: Path) -> None:
    """Write the bundle as ca/server/client .pem (0644) and .key (0600) files."""
    directory.mkdir(parents=True, exist_ok=True)
    for role, (cert_file, key_file) in _FILES.items():
        pair: KeyPair = getattr(bundle, role)
        write_private(directory / key_file, pair.key_pem)
        (directory / cert_file).write_bytes(pair.cert_pem)


def load_bundle(directory: Path) -> Bundle:
    pairs = {}
    for role, (cert_file, key_file) in _FILES.items():
        pairs[role] = KeyPair((directory / cert_file).read_bytes(), (directory / key_file).read_bytes())
    return Bundle(**pairs)


def load_or_create_bundle(stack: str, directory: Path) -> Bundle:
    """The stack's persisted bundle, created on first use so re-applies keep the same CA."""
    if all((directory / f).exists() for files in _FILES.values() for f in files):
        return load_bundle(directory)
    bundle = new_bundle(stack)
    save_bundle(bundle, directory)
    return bundle


SSH_KEY = "id_ed25519"  # under stack_dir(stack)/"ssh": private 0600, public beside it (.pub)


def load_or_create_ssh_key(directory: Path) -> str:
    """The stack's ed25519 public key (OpenSSH format), made on first use; private key 0600."""
    public = directory / f"{SSH_KEY}.pub"
    private = directory / SSH_KEY
    if private.exists() and public.exists():
        return public.read_text().strip()
    key = Ed25519PrivateKey.generate()
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.OpenSSH,
                            serialization.NoEncryption())
    write_private(private, pem)
    text = key.public_key().public_bytes(serialization.Encoding.OpenSSH, serialization.PublicFormat.OpenSSH).decode()
    public.write_text(f"{text} fogiac\n")
    return public.read_text().strip()
