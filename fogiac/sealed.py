"""Secrets sealed at rest: what a shared state store keeps of a stack's key material is never plaintext.

A stack's folder holds private keys (its CA, the VPN's and the edge's certificates, its SSH key, the
hosts' keys on the local target). Kept on the operator's disk they are protected by the folder's 0700;
kept in a shared bucket, anyone who can read the bucket could read them. So a store seals each such
object before it leaves the machine, as Pulumi's secrets providers do, with one of two providers:

- ``kms``: envelope encryption. A data key per object from the KMS key the manifest's ``state.kms_key``
  names (GenerateDataKey, with the object's name as encryption context); the object is encrypted with
  it, the data key itself is kept only encrypted, in the blob's header. Who may use the KMS key is
  IAM's business, and every use is in CloudTrail.
- ``passphrase``: a key derived with scrypt from ``$FOGIAC_STATE_PASSPHRASE`` and a random salt kept in
  the header (the salt is made once per sealer, so a whole stack costs one derivation).

Either way the content is AES-256-GCM with the object's name and the header as associated data: a
blob copied over another name, or a header edited (salt, key, provider), does not open. A blob is::

    fogiac-sealed 1 PROVIDER\\n      what sealed it (the format's version, the provider)
    {header JSON}\\n                  salt and scrypt's cost, or the KMS key and the encrypted data key
    nonce (12 bytes) ciphertext+tag

Opening reads the provider from the blob, so a stack sealed under a passphrase still opens after
``kms_key`` is set (the next write seals with the key). What cannot be opened is one line naming the
object and what is needed: the passphrase not set or wrong, the KMS key not accessible, or the blob
altered. boto3 is imported only when a KMS key is used.
"""

from __future__ import annotations

import base64
import functools
import hashlib
import hmac
import json
import os
import re
from collections.abc import Callable
from pathlib import PurePosixPath
from typing import Any, Protocol

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives.ciphers.aead import AESGCM
from cryptography.hazmat.primitives.kdf.scrypt import Scrypt

from fogiac import extras
from fogiac.certs import SSH_KEY
from fogiac.errors import StateError

PASSPHRASE_ENV = "FOGIAC_STATE_PASSPHRASE"
MAGIC = b"fogiac-sealed"
FORMAT = 1
PASSPHRASE, KMS = "passphrase", "kms"
_NONCE = 12
# scrypt's cost: 2**15 x 8 is 32 MiB and a fraction of a second, once per sealer (RFC 7914's interactive
# setting is 2**14). Opening honours what the header says, within bounds a hostile header cannot exceed.
_SCRYPT = {"n": 2**15, "r": 8, "p": 1}
_SCRYPT_MAX = {"n": 2**20, "r": 16, "p": 4}
_CHECK = b"fogiac-sealed passphrase check"
_CONTEXT = "fogiac:object"  # the KMS encryption context's key: the object's name

# What in a stack's folder is key material, by name (owners: fogiac.certs, fogiac.net.hostkey, the Pulumi
# engine's generated passphrase, a VPN client profile with its key inline), and by content (a PEM or
# OpenSSH private key anywhere, whatever the file is called).
_KEY_SUFFIXES = (".key", ".ovpn")
_KEY_NAMES = frozenset({SSH_KEY, "pulumi-passphrase"})
_PRIVATE_PEM = re.compile(rb"-----BEGIN [A-Z0-9 ]*PRIVATE KEY-----")


class Sealer(Protocol):
    """Seals an object of a stack before a store writes it, opens it after the store reads it."""

    def seal(self, name: str, data: bytes) -> bytes: ...

    def open(self, name: str, blob: bytes) -> bytes: ...


def sealer_for(kms_key: str | None, *, kms: Any | None = None) -> Sealer:
    """The sealer a store uses: envelope encryption under ``kms_key`` (an ARN or ``alias/...``) when one is
    named, else the passphrase in ``$FOGIAC_STATE_PASSPHRASE``. ``kms``: a KMS client (tests pass
    LocalStack's); by default one from boto3's usual configuration, made at the first use."""
    return KmsSealer(kms_key, kms=kms) if kms_key else PassphraseSealer()


def is_sealed(blob: bytes) -> bool:
    return blob.startswith(MAGIC + b" ")


def is_key_material(path: str, data: bytes | None = None) -> bool:
    """Whether a file of a stack's folder (``path`` relative to it, ``/``-separated) is key material a store
    must seal: certificates' private keys (``*.key``: the CA's, the VPN's, the edge's, a host's server key),
    the stack's SSH key, the Pulumi passphrase, a VPN profile, and any file whose ``data`` holds a private key."""
    name = PurePosixPath(path).name
    if name in _KEY_NAMES or name.endswith(_KEY_SUFFIXES):
        return True
    return data is not None and _PRIVATE_PEM.search(data) is not None


class PassphraseSealer:
    """AES-256-GCM under a key scrypt derives from ``$FOGIAC_STATE_PASSPHRASE``; the salt in each header."""

    provider = PASSPHRASE

    def __init__(self) -> None:
        self._salt = os.urandom(16)

    def seal(self, name: str, data: bytes) -> bytes:
        key = _derive(_passphrase(name), self._salt, **_SCRYPT)
        header = {"salt": _b64(self._salt), **_SCRYPT, "check": _check(key)}
        return _encrypt(PASSPHRASE, header, key, name, data)

    def open(self, name: str, blob: bytes) -> bytes:
        return open_blob(name, blob)


class KmsSealer:
    """Envelope encryption: a KMS data key per object, kept encrypted in the header."""

    provider = KMS

    def __init__(self, key: str, *, kms: Any | None = None) -> None:
        self.key = key
        self._kms = kms

    def client(self) -> Any:
        if self._kms is None:
            self._kms = _kms_client(self.key)
        return self._kms

    def seal(self, name: str, data: bytes) -> bytes:
        made = _kms_call(self.key, name, lambda: self.client().generate_data_key(
            KeyId=self.key, KeySpec="AES_256", EncryptionContext={_CONTEXT: name}))
        header = {"key": self.key, "data_key": _b64(made["CiphertextBlob"])}
        return _encrypt(KMS, header, bytes(made["Plaintext"]), name, data)

    def open(self, name: str, blob: bytes) -> bytes:
        return open_blob(name, blob, kms=lambda key: self.client())  # one client for every object it opens


def open_blob(name: str, blob: bytes, *, kms: Callable[[str], Any] | None = None) -> bytes:
    """The content of a sealed object stored as ``name``, by whichever provider sealed it; StateError (one
    line naming the object and the key needed) when it cannot be opened. ``kms``: the KMS client for the key
    a blob names (default: boto3's, made for it)."""
    provider, header, first, rest = _parse(name, blob)
    if provider == PASSPHRASE:
        try:
            salt = base64.b64decode(header["salt"], validate=True)
            cost = {k: int(header[k]) for k in ("n", "r", "p")}
            check = str(header["check"])
        except (KeyError, TypeError, ValueError):
            raise _altered(name) from None
        if not _sane(cost):
            raise _altered(name)
        key = _derive(_passphrase(name), salt, **cost)
        if not hmac.compare_digest(_check(key), check):
            raise StateError(f"{name}: ${PASSPHRASE_ENV} is not the passphrase it was sealed with; "
                             f"set the stack's passphrase to open it")
    else:
        key_id, data_key = header.get("key"), header.get("data_key")
        if not isinstance(key_id, str) or not isinstance(data_key, str):
            raise _altered(name)
        try:
            wrapped = base64.b64decode(data_key, validate=True)
        except ValueError:
            raise _altered(name) from None
        client = (kms or _kms_client)(key_id)
        key = bytes(_kms_call(key_id, name, lambda: client.decrypt(
            CiphertextBlob=wrapped, KeyId=key_id, EncryptionContext={_CONTEXT: name}))["Plaintext"])
    try:
        return AESGCM(key).decrypt(rest[:_NONCE], rest[_NONCE:], _aad(name, first))
    except (InvalidTag, ValueError):
        raise _altered(name) from None


# -- the blob -------------------------------------------------------------------------------------------

def _encrypt(provider: str, header: dict[str, Any], key: bytes, name: str, data: bytes) -> bytes:
    first = b"%s %d %s\n%s\n" % (MAGIC, FORMAT, provider.encode(),
                                 json.dumps(header, sort_keys=True, separators=(",", ":")).encode())
    nonce = os.urandom(_NONCE)
    return first + nonce + AESGCM(key).encrypt(nonce, data, _aad(name, first))


def _parse(name: str, blob: bytes) -> tuple[str, dict[str, Any], bytes, bytes]:
    """(provider, header, the bytes the tag covers besides the name, nonce + ciphertext)."""
    if not is_sealed(blob):
        raise StateError(f"{name}: not a sealed fogiac object (stored in plaintext, or by something else); refused")
    try:
        line, header_line, rest = blob.split(b"\n", 2)
        _, version, provider = line.decode("ascii").split(" ")
        header = json.loads(header_line)
    except ValueError:
        raise _altered(name) from None
    if not version.isdigit():
        raise _altered(name)
    if int(version) > FORMAT:
        raise StateError(f"{name}: sealed by a newer fogiac (sealed format {version}, this one reads {FORMAT}); "
                         f"upgrade fogiac")
    if provider not in (PASSPHRASE, KMS) or not isinstance(header, dict) or len(rest) < _NONCE + 16:
        raise _altered(name)
    return provider, header, line + b"\n" + header_line + b"\n", rest


def _aad(name: str, first: bytes) -> bytes:
    return b"fogiac-sealed object\0" + name.encode() + b"\0" + first


def _altered(name: str) -> StateError:
    return StateError(f"{name}: the sealed object does not open under this name (altered since it was sealed, "
                      f"or copied from another name); refused")


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


# -- the passphrase -------------------------------------------------------------------------------------

def _passphrase(name: str) -> str:
    given = os.environ.get(PASSPHRASE_ENV)
    if not given:
        raise StateError(f"{name}: the stack's secrets are sealed with a passphrase and {PASSPHRASE_ENV} is not "
                         f"set; set it to the stack's passphrase (or name a KMS key in state.kms_key)")
    return given


@functools.lru_cache(maxsize=8)
def _derive(passphrase: str, salt: bytes, *, n: int, r: int, p: int) -> bytes:
    return Scrypt(salt=salt, length=32, n=n, r=r, p=p).derive(passphrase.encode())


def _sane(cost: dict[str, int]) -> bool:
    """scrypt's cost as a header gives it: n a power of two, each within what a hostile header may ask for."""
    n = cost["n"]
    return 1 < n <= _SCRYPT_MAX["n"] and n & (n - 1) == 0 and all(0 < cost[k] <= _SCRYPT_MAX[k] for k in ("r", "p"))


def _check(key: bytes) -> str:
    """A short value that tells a wrong passphrase from an altered blob (it says no more than the tag does)."""
    return hmac.new(key, _CHECK, hashlib.sha256).hexdigest()[:16]


# -- KMS --------------------------------------------------------------------------------------------------

def _kms_client(key: str) -> Any:
    """boto3's KMS client, from the usual AWS variables (``AWS_ENDPOINT_URL`` too); the region an ARN names
    when none is configured."""
    boto3 = extras.need("boto3", extra="aws")
    region = key.split(":")[3] if key.startswith("arn:") and key.count(":") >= 5 else None
    session = boto3.session.Session()
    return session.client("kms", region_name=session.region_name or region or None)


def _kms_call(key: str, name: str, call: Any) -> Any:
    """``call()``, with botocore's errors as one line: the key not accessible, or (Decrypt refusing the
    data key) the object altered."""
    botocore = extras.need("botocore.exceptions", extra="aws")
    try:
        return call()
    except botocore.ClientError as err:
        code = str(err.response.get("Error", {}).get("Code", "error"))
        if code in ("InvalidCiphertextException", "IncorrectKeyException"):
            raise _altered(name) from None
        said = " ".join(str(err.response.get("Error", {}).get("Message", "")).split())
        raise StateError(f"{name}: KMS key {key} not accessible ({code}: {said}); the stack's secrets are sealed "
                         f"with it: use credentials allowed to use it") from None
    except botocore.BotoCoreError as err:
        said = " ".join(str(err).split())
        raise StateError(f"{name}: KMS key {key} not accessible ({said}); the stack's secrets are sealed "
                         f"with it") from None
