"""Mutual TLS 1.3 for the link: the cloud end shows server.pem, the edge end client.pem,
and each accepts only certificates signed by the stack's ca.pem.

The relay's own certificate names live here too, beside the contexts that check them (as the Zenoh
router's do in :mod:`fogiac.net.zenoh.tls`): :func:`relay_name` for a host's cloud end and
:func:`write_relay_lab` for a relay run by hand. :mod:`fogiac.certs` keeps what every middleware
shares (the CA, each edge's identity, signing a host's CSR).
"""

from __future__ import annotations

import ssl
from pathlib import Path

from cryptography import x509

from fogiac.certs import edge_identity, issue, new_ca, save_pair
from fogiac.net.relay.errors import RelayError


def relay_name(stack: str, host: str) -> str:
    """The name in ``host``'s relay certificate, which the edge relay dialing that host checks."""
    return f"{host}.relay.{stack}.fogiac"


def write_relay_lab(stack: str, directory: Path) -> str:
    """For a relay run by hand (``fogiac relay certs``): ca, client and one cloud-end server
    certificate (server.pem/.key) in ``directory``; returns the server's name. A stack's hosts
    never get these: each makes its own key at provisioning."""
    ca = new_ca(f"fogiac CA {stack}")
    name = relay_name(stack, "server")
    save_pair(directory, "ca", ca)
    save_pair(directory, "server", issue(ca, name, server=True, dns_names=(name,)))
    save_pair(directory, "client", issue(ca, edge_identity(stack, None), server=False))
    return name


def _need(directory: Path, *names: str) -> list[Path]:
    paths = [Path(directory) / n for n in names]
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise RelayError(
            f"certificate directory {directory} lacks {', '.join(missing)} (run `fogiac certs {directory}`)"
        )
    return paths


def _base(protocol: int) -> ssl.SSLContext:
    ctx = ssl.SSLContext(protocol)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_3
    ctx.verify_mode = ssl.CERT_REQUIRED
    return ctx


def server_context(certs: Path) -> ssl.SSLContext:
    ca, cert, key = _need(certs, "ca.pem", "server.pem", "server.key")
    ctx = _base(ssl.PROTOCOL_TLS_SERVER)
    ctx.load_cert_chain(cert, key)
    ctx.load_verify_locations(cafile=str(ca))
    # No session tickets: reader and writer threads share the socket, and a ticket written
    # by SSL_read on the server would race the writer's SSL_write.
    ctx.num_tickets = 0
    return ctx


def client_context(certs: Path, client: str = "client") -> ssl.SSLContext:
    """The edge's side; ``client``: the stem of its pair's files (each edge has its own, which names it)."""
    ca, cert, key = _need(certs, "ca.pem", f"{client}.pem", f"{client}.key")
    ctx = _base(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = True
    ctx.load_cert_chain(cert, key)
    ctx.load_verify_locations(cafile=str(ca))
    return ctx


def expected_server_name(certs: Path, override: str | None = None) -> str:
    """The DNS name the cloud end's certificate must carry: ``override`` or server.pem's SAN."""
    if override:
        return override
    path = Path(certs) / "server.pem"
    if not path.is_file():
        raise RelayError(f"{path} is missing: give the cloud certificate's name with --server-name")
    cert = x509.load_pem_x509_certificate(path.read_bytes())
    try:
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        raise RelayError(f"{path} has no subjectAltName: give --server-name") from None
    dns = names.get_values_for_type(x509.DNSName)
    if not dns:
        raise RelayError(f"{path} has no DNS name in its subjectAltName: give --server-name")
    return dns[0]
