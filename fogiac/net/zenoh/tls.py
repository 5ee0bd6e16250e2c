"""Certificates for Zenoh routers: one per cloud host and one for the edge, all from fogiac's CA.

A cloud router's key is made on its host and its certificate names the address the edge dials
(the edge checks it: ``verify_name_on_connect``); see :mod:`fogiac.net.hostcert`. The
edge's carries the common name the cloud routers' access control recognises. Keys are written
0600 (:func:`fogiac.certs.write_private`).
"""

from __future__ import annotations

from pathlib import Path

from fogiac.certs import KeyPair, issue, write_private
from fogiac.net.zenoh.config import TlsFiles
from fogiac.net.zenoh.middleware import ZENOH


def host_name(stack: str, host: str) -> str:
    return f"{host}.router.{stack}.fogiac"


def edge_name(stack: str, edge: str | None = None) -> str:
    """The common name of ``edge``'s router certificate, its identity at the cloud routers (None: the one edge
    of today's manifests, with the name it always had; else :attr:`fogiac.plan.model.EdgeSpec.named`)."""
    return f"edge.router.{stack}.fogiac" if edge is None else ZENOH.robot_certificate(stack, edge)


def edge_pair(ca: KeyPair, *, stack: str, edge: str | None = None) -> KeyPair:
    return issue(ca, edge_name(stack, edge), server=False)


def write_files(directory: Path, name: str, pair: KeyPair, ca: KeyPair) -> TlsFiles:
    """Write ``name``.pem/.key and ca.pem under ``directory``; the paths a router config names."""
    directory.mkdir(parents=True, exist_ok=True)
    cert, key, ca_file = directory / f"{name}.pem", directory / f"{name}.key", directory / "ca.pem"
    write_private(key, pair.key_pem)
    cert.write_bytes(pair.cert_pem)
    ca_file.write_bytes(ca.cert_pem)
    return TlsFiles(ca=str(ca_file), cert=str(cert), key=str(key))
