"""Secrets sealed under a KMS key (fogiac.sealed's envelope encryption), against LocalStack's KMS: a data key
per object, kept only encrypted in the blob; the object's name bound by KMS's encryption context and by
the cipher; a key that cannot be used is one line naming it."""

from __future__ import annotations

import base64
import json
import uuid
from typing import Any

import pytest

from fogiac import certs, sealed
from fogiac.errors import StateError


def _key(kms: Any) -> tuple[str, str]:
    """A fresh symmetric key and an alias for it: (ARN, alias)."""
    arn = kms.create_key(Description="fogiac sealed test")["KeyMetadata"]["Arn"]
    alias = f"alias/fogiac-test-{uuid.uuid4().hex[:8]}"
    kms.create_alias(AliasName=alias, TargetKeyId=arn)
    return arn, alias


def _header(blob: bytes) -> dict[str, Any]:
    first, header, _ = blob.split(b"\n", 2)
    assert first == b"fogiac-sealed 1 kms"
    return dict(json.loads(header))


def test_round_trip_under_an_alias_and_an_arn(kms: Any) -> None:
    arn, alias = _key(kms)
    secret = certs.new_ca("fogiac test CA").key_pem
    for key in (alias, arn):
        blob = sealed.sealer_for(key).seal("certs/ca.key", secret)  # its own client, from the AWS_* variables
        header = _header(blob)
        assert header["key"] == key
        assert b"PRIVATE KEY" not in blob
        assert sealed.sealer_for(key, kms=kms).open("certs/ca.key", blob) == secret
        assert sealed.open_blob("certs/ca.key", blob) == secret  # opened by what the blob names
    one, two = (sealed.sealer_for(alias, kms=kms).seal("certs/ca.key", secret) for _ in range(2))
    assert _header(one)["data_key"] != _header(two)["data_key"]  # a data key per object


def test_the_data_key_is_kept_only_encrypted(kms: Any) -> None:
    _, alias = _key(kms)
    blob = sealed.sealer_for(alias, kms=kms).seal("ssh/id_ed25519", b"k" * 64)
    wrapped = base64.b64decode(_header(blob)["data_key"])
    plain = kms.decrypt(CiphertextBlob=wrapped, EncryptionContext={"fogiac:object": "ssh/id_ed25519"})["Plaintext"]
    assert len(plain) == 32 and plain not in blob and wrapped != plain


ALTERED = r"^certs/ca.key: the sealed object does not open under this name \(altered since it was sealed, or copied " \
          r"from another name\); refused$"


def test_a_name_swap_and_a_tampered_blob_are_refused(kms: Any) -> None:
    _, alias = _key(kms)
    sealer = sealed.sealer_for(alias, kms=kms)
    client_key = sealer.seal("certs/client.key", b"the client's key")
    with pytest.raises(StateError, match=ALTERED):  # KMS's encryption context names the object
        sealer.open("certs/ca.key", client_key)
    blob = sealer.seal("certs/ca.key", b"the CA's key")
    header = _header(blob)
    wrapped = bytearray(base64.b64decode(header["data_key"]))
    wrapped[-1] ^= 1
    edited = blob.replace(header["data_key"].encode(), base64.b64encode(bytes(wrapped)))
    flipped = blob[:-1] + bytes([blob[-1] ^ 1])
    for bad in (edited, flipped):
        with pytest.raises(StateError, match=ALTERED):
            sealer.open("certs/ca.key", bad)


def test_a_key_that_cannot_be_used_is_one_line_naming_it(kms: Any) -> None:
    with pytest.raises(StateError, match=r"^certs/ca.key: KMS key alias/fogiac-no-such-key not accessible "
                                         r"\(NotFoundException: [^\n]*\); the stack's secrets are sealed with it"):
        sealed.sealer_for("alias/fogiac-no-such-key", kms=kms).seal("certs/ca.key", b"x")
    arn, alias = _key(kms)
    blob = sealed.sealer_for(alias, kms=kms).seal("certs/ca.key", b"x")
    kms.disable_key(KeyId=arn)
    with pytest.raises(StateError, match=rf"^certs/ca.key: KMS key {alias} not accessible \(\w+: [^\n]*\); the "
                                         r"stack's secrets are sealed with it: use credentials allowed to use it$"):
        sealed.sealer_for(alias, kms=kms).open("certs/ca.key", blob)


def test_a_passphrase_sealed_stack_still_opens_once_a_key_is_named(kms: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(sealed.PASSPHRASE_ENV, "lab passphrase")
    blob = sealed.sealer_for(None).seal("certs/vpn.key", b"vpn key")
    _, alias = _key(kms)
    assert sealed.sealer_for(alias, kms=kms).open("certs/vpn.key", blob) == b"vpn key"
