"""Certificates for the stack's mutual TLS: one CA, the Client VPN endpoint's, one per edge, one per host.

AWS Client VPN requires RSA 2048 keys, so everything here is RSA 2048 for one code path.
The relay (edge and cloud ends) and the Client VPN endpoint trust the same CA. The operator's
machine keeps the CA key and the keys it uses itself (the VPN endpoint's, imported into ACM, and
the edge's client key); a host's key (its relay's, its Zenoh router's) is made on the host and
only its CSR comes here to be signed (:func:`sign_csr`). Private keys are written 0600 and never
printed; callers that put them into Pulumi mark them secret.

Each edge has a client certificate of its own, whose name is its identity (the relay's cloud ends keep a
session per identity): the edge named after the stack, the one today's manifests make (``edge:``), keeps the files
it always had (``client.pem``/``.key``, ``client.<stack>.fogiac``); any other edge ``edge-<name>.pem``/``.key``
for ``<name>.edge.<stack>.fogiac`` (:func:`load_or_create_edges`).
"""

from __future__ import annotations

import datetime as _dt
import ipaddress
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from fogiac.certnames import server_name
from fogiac.errors import CertError
from fogiac.state import write_atomic

_VALID_DAYS = 825
_RENEW_DAYS = 30  # a host's certificate is reissued when it has less left


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
    """What the operator's machine holds for a stack: the CA, the Client VPN endpoint's server
    certificate (imported into ACM, never sent to a host) and the edge's client certificate."""

    ca: KeyPair
    vpn: KeyPair
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


def _sign(
    ca: KeyPair, public_key: rsa.RSAPublicKey, common_name: str, *, server: bool,
    dns_names: tuple[str, ...] = (), ip_addresses: tuple[str, ...] = (),
) -> bytes:
    ca_cert = x509.load_pem_x509_certificate(ca.cert_pem)
    ca_key = serialization.load_pem_private_key(ca.key_pem, password=None)
    now = _dt.datetime.now(_dt.timezone.utc)
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(ca_cert.subject)
        .public_key(public_key)
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
    return builder.sign(ca_key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM)  # type: ignore[arg-type]


def issue(
    ca: KeyPair,
    common_name: str,
    *,
    server: bool,
    dns_names: tuple[str, ...] = (),
    ip_addresses: tuple[str, ...] = (),
) -> KeyPair:
    """Issue a leaf certificate and its new key, signed by ``ca``; server ones carry serverAuth,
    others clientAuth. Only for keys this machine keeps: a host's key is made on the host.

    AWS ACM only imports a server certificate whose subject has a domain name, so callers give
    server certificates a DNS-style common name and repeat it in ``dns_names``.
    """
    key = _new_key()
    cert = _sign(ca, key.public_key(), common_name, server=server, dns_names=dns_names, ip_addresses=ip_addresses)
    return KeyPair(cert, _key_pem(key))


def split_addresses(addresses: tuple[str, ...]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """``(dns_names, ip_addresses)``: how each address a peer dials goes into a subjectAltName."""
    dns: list[str] = []
    ips: list[str] = []
    for address in addresses:
        try:
            ips.append(str(ipaddress.ip_address(address)))
        except ValueError:
            dns.append(address)
    return tuple(dns), tuple(ips)


def sign_csr(ca: KeyPair, csr_pem: bytes, name: str, *, addresses: tuple[str, ...] = ()) -> bytes:
    """A server certificate for ``name`` (and ``addresses``, IPs or DNS names) over a host's CSR key (PEM).

    Only the CSR's key is taken, after its signature proves the host holds the private half:
    the names are fogiac's, whatever the request asks for. ``addresses`` are for peers that check
    the address they dialed (Zenoh's ``verify_name_on_connect``); the relay checks ``name``.
    """
    try:
        csr = x509.load_pem_x509_csr(csr_pem)
    except ValueError:
        raise CertError(f"the certificate request for {name} is not a PEM CSR") from None
    key = csr.public_key()
    if not csr.is_signature_valid:
        raise CertError(f"the certificate request for {name} is not signed by its own key")
    if not isinstance(key, rsa.RSAPublicKey) or key.key_size < 2048:
        raise CertError(f"the certificate request for {name} does not carry an RSA key of 2048 bits or more")
    dns, ips = split_addresses(addresses)
    return _sign(ca, key, name, server=True, dns_names=(name, *dns), ip_addresses=ips)


def serves(ca: KeyPair, cert_pem: bytes, name: str, public_key_pem: bytes, *, addresses: tuple[str, ...] = (),
           days: int = _RENEW_DAYS) -> bool:
    """Whether ``cert_pem`` is ``ca``'s certificate for ``name`` (and every one of ``addresses``) over this
    public key, valid ``days`` more."""
    try:
        cert = x509.load_pem_x509_certificate(cert_pem)
        cert.verify_directly_issued_by(x509.load_pem_x509_certificate(ca.cert_pem))
        key = serialization.load_pem_public_key(public_key_pem)
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except (ValueError, TypeError, InvalidSignature, x509.ExtensionNotFound):
        return False
    spki = serialization.PublicFormat.SubjectPublicKeyInfo
    same_key = (cert.public_key().public_bytes(serialization.Encoding.DER, spki)
                == key.public_bytes(serialization.Encoding.DER, spki))
    left = cert.not_valid_after_utc - _dt.datetime.now(_dt.timezone.utc)
    dns, ips = split_addresses(addresses)
    named = set(dns + (name,)) <= set(names.get_values_for_type(x509.DNSName))
    named = named and {ipaddress.ip_address(a) for a in ips} <= set(names.get_values_for_type(x509.IPAddress))
    return same_key and named and left > _dt.timedelta(days=days)


def _vpn_pair(ca: KeyPair, stack: str) -> KeyPair:
    name = server_name(stack)
    return issue(ca, name, server=True, dns_names=(name,))


def _client_pair(ca: KeyPair, stack: str) -> KeyPair:
    return issue(ca, edge_identity(stack, None), server=False)


_EDGE_NAME = re.compile(r"^[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?$")  # one DNS label: it goes into a certificate


def edge_identity(stack: str, edge: str | None) -> str:
    """The name in ``edge``'s client certificate, which cloud ends tell edges apart by: today's one edge
    (None: the manifest's ``edge:`` block, named after the stack) keeps the name it always had."""
    if edge is None:
        return f"client.{stack}.fogiac"
    if not _EDGE_NAME.match(edge):
        raise CertError(f"edge {edge!r}: an edge's name must be one DNS label (a-z, 0-9, '-', up to 63)")
    return f"{edge}.edge.{stack}.fogiac"


def edge_role(stack: str, edge: str | None) -> str:
    """The stem of ``edge``'s certificate files in the stack's certs folder (``ROLE.pem``, ``ROLE.key``)."""
    return "client" if edge is None else f"edge-{edge}"


def new_bundle(stack: str) -> Bundle:
    ca = new_ca(f"fogiac CA {stack}")
    return Bundle(ca=ca, vpn=_vpn_pair(ca, stack), client=_client_pair(ca, stack))


def write_private(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` with mode 0600 from the first byte (never world-readable)."""
    write_atomic(path, data, mode=0o600)


_ROLES = ("ca", "vpn", "client")  # each as ROLE.pem (0644) and ROLE.key (0600)
_SHARED_SERVER = ("server.pem", "server.key")  # before per-host keys: one server key sent to every host


def save_pair(directory: Path, role: str, pair: KeyPair) -> None:
    """Write ``role``.key (0600) and ``role``.pem (0644) under ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    write_private(directory / f"{role}.key", pair.key_pem)
    (directory / f"{role}.pem").write_bytes(pair.cert_pem)


def _load_pair(directory: Path, role: str) -> KeyPair | None:
    cert, key = directory / f"{role}.pem", directory / f"{role}.key"
    return KeyPair(cert.read_bytes(), key.read_bytes()) if cert.exists() and key.exists() else None


def save_bundle(bundle: Bundle, directory: Path) -> None:
    """Write the bundle as ca/vpn/client .pem (0644) and .key (0600) files."""
    for role in _ROLES:
        save_pair(directory, role, getattr(bundle, role))


def load_bundle(directory: Path) -> Bundle:
    pairs = {role: _load_pair(directory, role) for role in _ROLES}
    missing = [role for role, pair in pairs.items() if pair is None]
    if missing:
        raise CertError(f"certificate folder {directory} lacks {', '.join(f'{r}.pem/.key' for r in missing)}")
    return Bundle(**pairs)  # type: ignore[arg-type]


def load_or_create_bundle(stack: str, directory: Path) -> Bundle:
    """The stack's persisted bundle, created on first use so re-applies keep the same CA.

    A folder from before per-host keys keeps its CA and client certificate, gains a VPN
    certificate of its own and loses the shared server key (hosts get their own on the next up).
    """
    ca = _load_pair(directory, "ca")
    if ca is None:
        bundle = new_bundle(stack)
        save_bundle(bundle, directory)
    else:
        made = {"vpn": _vpn_pair, "client": _client_pair}
        for role, make in made.items():
            if _load_pair(directory, role) is None:
                save_pair(directory, role, make(ca, stack))
        bundle = load_bundle(directory)
    for name in _SHARED_SERVER:
        (directory / name).unlink(missing_ok=True)
    return bundle


def load_or_create_edges(stack: str, directory: Path, edges: Iterable[str | None]) -> dict[str | None, KeyPair]:
    """Each edge's client pair (name -> pair; :attr:`fogiac.plan.model.EdgeSpec.named`), issued by the stack's
    CA on first use and kept. The stack's bundle is loaded (or made) first, so today's one edge (None) is
    its ``client`` pair as before."""
    bundle = load_or_create_bundle(stack, directory)
    pairs: dict[str | None, KeyPair] = {}
    for edge in edges:
        role = edge_role(stack, edge)
        pair = bundle.client if role == "client" else _load_pair(directory, role)
        if pair is None:
            pair = issue(bundle.ca, edge_identity(stack, edge), server=False)
            save_pair(directory, role, pair)
        pairs[edge] = pair
    return pairs


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
