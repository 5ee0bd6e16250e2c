"""A real TLS 1.3 handshake between the relay's two contexts, for name and trust checks."""

from __future__ import annotations

import re
import socket
import ssl
import threading
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import serialization

from fogiac.net.relay.tls import client_context, server_context


def handshake(server_certs: Path, edge_certs: Path, name: str) -> str | None:
    """Dial a cloud end showing ``server_certs``' server.pem, expecting ``name``; None if the edge accepted it."""
    ours, theirs = socket.socketpair()
    ours.settimeout(10)
    theirs.settimeout(10)

    def serve() -> None:
        try:
            with server_context(server_certs).wrap_socket(theirs, server_side=True) as tls:
                tls.recv(1)  # TLS 1.3 checks the client's certificate after the server's Finished
        except (ssl.SSLError, OSError):
            pass

    worker = threading.Thread(target=serve, daemon=True)
    worker.start()
    try:
        with client_context(edge_certs).wrap_socket(ours, server_hostname=name) as tls:
            tls.sendall(b"x")
        return None
    except ssl.SSLCertVerificationError as err:
        return err.verify_message
    finally:
        ours.close()
        worker.join(10)
        theirs.close()


_PEM_KEY = re.compile(rb"-----BEGIN (?:RSA |EC )?PRIVATE KEY-----.+?-----END (?:RSA |EC )?PRIVATE KEY-----", re.S)
_SPKI = (serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)


def dial(address: tuple[str, int], edge_certs: Path, name: str) -> str | None:
    """Dial a running cloud end as the edge relay does, expecting ``name``; None if accepted."""
    try:
        with socket.create_connection(address, timeout=10) as raw, \
                client_context(edge_certs).wrap_socket(raw, server_hostname=name):
            return None
    except ssl.SSLCertVerificationError as err:
        return err.verify_message


def private_keys_under(folder: Path) -> dict[Path, list[bytes]]:
    """The public halves (DER) of every PEM private key in any file below ``folder`` (profiles included)."""
    found: dict[Path, list[bytes]] = {}
    for path in folder.rglob("*"):
        if path.is_file() and not path.is_symlink():
            keys = [serialization.load_pem_private_key(block, password=None).public_key().public_bytes(*_SPKI)
                    for block in _PEM_KEY.findall(path.read_bytes())]
            if keys:
                found[path] = keys
    return found


def public_der(cert_pem: bytes) -> bytes:
    """The public key (DER) of a PEM certificate."""
    return x509.load_pem_x509_certificate(cert_pem).public_key().public_bytes(*_SPKI)
