"""Issue 33: ``fogiac state migrate`` moves an aws stack's Pulumi state with its record.

A stack deployed from a member's folder keeps Pulumi's file backend beside its record
(``<stack>/pulumi/.pulumi/``); once the record is in the bucket, the engine's backend is the bucket's
``s3://BUCKET/PREFIX`` (:func:`fogiac.pulumi_engine.workspace.workspace_env`), so the checkpoints must be
there too, at ``PREFIX/.pulumi/``, or the next ``up`` would create every resource again and ``down`` would
find nothing to destroy. The tree is written as Pulumi's file backend lays it out (project-scoped, meta
version 1; the CLI is not installed here), against LocalStack S3; what the engine would read is checked
through :func:`fogiac.targets.aws.engine.known_ids`, which reads the checkpoints where the engine keeps them.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import Any

import pytest

from fogiac.cli.state import migrate
from fogiac.pulumi_engine.workspace import BACKEND_DIR, workspace_env
from fogiac.state import StackState
from fogiac.targets.aws.engine import known_ids
from stacks.aws import LAYERS, PROJECT

pytestmark = pytest.mark.localstack


def _objects(s3: Any, bucket: str) -> dict[str, bytes]:
    keys = [o["Key"] for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket)
            for o in page.get("Contents", [])]
    return {key: s3.get_object(Bucket=bucket, Key=key)["Body"].read() for key in keys}


def _tree(stack: str) -> dict[str, bytes]:
    """A file backend as Pulumi leaves it after ``up`` of both layers (and a dead update's lock)."""
    tree = {"meta.yaml": b"version: 1\n"}
    for layer in LAYERS:
        name = f"{stack}-{layer}"
        checkpoint = {"version": 3, "checkpoint": {"stack": name, "latest": {
            "secrets_providers": {"type": "passphrase", "state": {"salt": "v1:c2FsdA==:v1:abc:def"}},
            "resources": [{"urn": f"urn:pulumi:{name}::{PROJECT}::aws:ec2/vpc:Vpc::{layer}", "custom": True,
                           "id": f"vpc-{layer}{stack[-6:]}", "type": "aws:ec2/vpc:Vpc"}]}}}
        tree[f"stacks/{PROJECT}/{name}.json"] = json.dumps(checkpoint).encode()
        tree[f"history/{PROJECT}/{name}/{name}-1764300000000000000.history.json"] = b'{"kind": "update"}'
        tree[f"locks/{PROJECT}/{name}/0b1c.json"] = b'{"pid": 1}'
    return tree


def test_migrate_moves_the_pulumi_backend_where_the_engine_finds_it_and_back(
        aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import boto3

    s3 = boto3.client("s3")
    bucket = f"fogiac-backend-{uuid.uuid4().hex[:10]}"
    s3.create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    url = f"s3://{bucket}/lab"
    other = f"other{uuid.uuid4().hex[:6]}-dev"  # a stack another member already keeps in the bucket
    s3.put_object(Bucket=bucket, Key="lab/.pulumi/meta.yaml", Body=b"version: 1\n")
    s3.put_object(Bucket=bucket, Key=f"lab/.pulumi/stacks/{PROJECT}/{other}-network.json", Body=b"{}")

    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    monkeypatch.setenv("FOGIAC_STATE_PASSPHRASE", "the lab's passphrase")
    monkeypatch.delenv("FOGIAC_STATE_URL", raising=False)
    stack = f"cloud{uuid.uuid4().hex[:6]}-dev"
    StackState(stack).set("deployment", {"target": "aws", "state": "complete"})
    local = StackState(stack).ensure() / BACKEND_DIR / ".pulumi"
    tree = _tree(stack)
    for rel, data in tree.items():
        (local / rel).parent.mkdir(parents=True, exist_ok=True)
        (local / rel).write_bytes(data)
    (StackState(stack).folder / "pulumi-passphrase").write_text("the stack's own passphrase\n")
    ids = {f"vpc-{layer}{stack[-6:]}" for layer in LAYERS}
    assert ids <= known_ids(stack)

    said = migrate(stack, to=url, source_url=None)
    assert f"to {url}/{stack}/record.json" in said, said
    objects = _objects(s3, bucket)
    for rel, data in tree.items():  # where the engine's s3:// backend (the same prefix) reads them
        if not rel.startswith("locks/"):
            assert objects[f"lab/.pulumi/{rel}"] == data, rel
    assert not [k for k in objects if "/locks/" in k], "a dead update's Pulumi lock went to the bucket"
    assert objects[f"lab/.pulumi/stacks/{PROJECT}/{other}-network.json"] == b"{}"
    assert not local.exists(), "the folder kept a second copy of Pulumi's state"

    monkeypatch.setenv("FOGIAC_STATE_URL", url)  # another member, another machine: reads them from the bucket
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "member-b"))
    assert workspace_env(stack)["PULUMI_BACKEND_URL"] == url
    assert ids <= known_ids(stack)

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    said = migrate(stack, to="folder", source_url=url)
    monkeypatch.delenv("FOGIAC_STATE_URL")
    assert workspace_env(stack)["PULUMI_BACKEND_URL"] == (StackState(stack).folder / BACKEND_DIR).as_uri()
    back = {p.relative_to(local).as_posix(): p.read_bytes() for p in local.rglob("*") if p.is_file()}
    assert back == {rel: data for rel, data in tree.items() if not rel.startswith("locks/")}
    assert ids <= known_ids(stack)
    left = _objects(s3, bucket)
    assert not [k for k in left if stack in k and "/.pulumi/" in k], "the bucket kept the stack's Pulumi state"
    assert left[f"lab/.pulumi/stacks/{PROJECT}/{other}-network.json"] == b"{}"  # the other stack's stays
    assert "lab/.pulumi/meta.yaml" in left
