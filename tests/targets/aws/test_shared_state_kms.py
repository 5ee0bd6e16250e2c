"""Issue 33: a stack's key material in the shared bucket is sealed under the lab's KMS key, end to end.

Against LocalStack S3 and KMS: member A (``FOGIAC_STATE_URL`` and ``FOGIAC_STATE_KMS_KEY``, no passphrase)
makes the stack's CA, certificates and SSH key as ``up`` does and writes the record under the lock; every
object in the bucket is then listed and grepped: no private key in plaintext, not even one line of it.
Member B (another state folder, the same URL and key) reads the same keys back, 0600. Once the key can no
longer be used (disabled), opening them is one line naming the object and the key.
"""

from __future__ import annotations

import stat
import uuid
from pathlib import Path
from typing import Any

import pytest

from fogiac.certs import load_or_create_bundle, load_or_create_ssh_key
from fogiac.errors import StateError
from fogiac.state import StackState

pytestmark = pytest.mark.localstack


def _objects(s3: Any, bucket: str) -> dict[str, bytes]:
    keys = [o["Key"] for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket)
            for o in page.get("Contents", [])]
    return {key: s3.get_object(Bucket=bucket, Key=key)["Body"].read() for key in keys}


def test_no_object_holds_a_private_key_in_plaintext_and_a_member_with_the_key_reads_them(
        kms: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import boto3

    s3 = boto3.client("s3")
    bucket = f"fogiac-kms-{uuid.uuid4().hex[:10]}"
    s3.create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    arn = kms.create_key(Description="the lab's state key")["KeyMetadata"]["Arn"]
    alias = f"alias/fogiac-lab-{uuid.uuid4().hex[:8]}"
    kms.create_alias(AliasName=alias, TargetKeyId=arn)
    monkeypatch.delenv("FOGIAC_STATE_PASSPHRASE", raising=False)
    monkeypatch.setenv("FOGIAC_STATE_URL", f"s3://{bucket}/lab")
    monkeypatch.setenv("FOGIAC_STATE_KMS_KEY", alias)
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "a"))
    stack = f"sealed{uuid.uuid4().hex[:6]}-dev"

    a = StackState(stack)
    with a.lock(operation="up"):
        load_or_create_bundle(stack, a.ensure() / StackState.CERTS)
        load_or_create_ssh_key(a.ssh_dir)
        a.set("deployment", {"target": "aws", "state": "partial"})
    keys = {p.relative_to(a.folder).as_posix(): p.read_bytes() for p in a.folder.rglob("*")
            if p.is_file() and (b"PRIVATE KEY" in p.read_bytes())}
    assert len(keys) >= 2, sorted(keys)  # the CA's and the SSH key at least

    objects = _objects(s3, bucket)
    assert {f"lab/{stack}/files/{rel}" for rel in keys} <= set(objects)
    lines = {line for data in keys.values() for line in data.splitlines()
             if len(line) >= 16 and b"-----" not in line}  # each line of each key's body
    for key, body in objects.items():
        assert b"PRIVATE KEY" not in body and b"OPENSSH" not in body, key
        assert not [line for line in lines if line in body], f"{key} holds a line of a private key"

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "b"))  # member B's machine
    b = StackState(stack)
    for rel, data in keys.items():
        path = b.folder / rel
        assert path.read_bytes() == data, rel
        assert stat.S_IMODE(path.stat().st_mode) == 0o600, rel

    kms.disable_key(KeyId=arn)  # a member whose credentials may not use the key is told which key
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "c"))
    with pytest.raises(StateError) as failed:
        StackState(stack).folder  # noqa: B018 - the first use pulls (and opens) the files
    line = str(failed.value)
    assert "\n" not in line and f"KMS key {alias} not accessible" in line and "sealed with it" in line, line
