"""Run ON a host (``python -c``): its server key (relay, Zenoh router) is made and kept there; only a CSR leaves.

Standalone on purpose (the standard library and ``cryptography``, which the relay's cloud end
needs anyway), so the host needs nothing of fogiac on its path to run it.

``show DIR``: one JSON line with DIR/server.pem's text and DIR/server.key's public half (null
where missing or unreadable). ``new DIR NAME``: a fresh RSA 2048 key replaces DIR/server.key
(0600 from the first byte) and its CSR for NAME goes to stdout.
"""

from __future__ import annotations

import json
import os
import sys

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import NameOID


def _show(folder: str) -> dict[str, str | None]:
    out: dict[str, str | None] = {"cert": None, "public": None}
    try:
        with open(os.path.join(folder, "server.pem")) as f:
            out["cert"] = f.read()
        with open(os.path.join(folder, "server.key"), "rb") as k:
            key = serialization.load_pem_private_key(k.read(), password=None)
        out["public"] = key.public_key().public_bytes(
            serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo).decode()
    except (OSError, ValueError, TypeError):
        pass
    return out


def _new(folder: str, name: str) -> bytes:
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                            serialization.NoEncryption())
    os.makedirs(folder, mode=0o700, exist_ok=True)
    tmp = os.path.join(folder, f".server.key.{os.getpid()}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(pem)
    os.replace(tmp, os.path.join(folder, "server.key"))
    csr = (x509.CertificateSigningRequestBuilder()
           .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
           .sign(key, hashes.SHA256()))
    return csr.public_bytes(serialization.Encoding.PEM)


def main(argv: list[str]) -> int:
    if len(argv) == 2 and argv[0] == "show":
        print(json.dumps(_show(argv[1])))
        return 0
    if len(argv) == 3 and argv[0] == "new":
        sys.stdout.write(_new(argv[1], argv[2]).decode())
        return 0
    print("usage: hostkey.py show DIR | new DIR NAME", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
