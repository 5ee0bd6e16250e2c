"""Issue 33: what one lab member deployed is fogiac's, not a stranger, on every member's machine.

Preflight compares the VPCs and instances tagged with a stack against the ids fogiac's state knows
(:func:`fogiac.targets.aws.engine.known_ids`) and tells the operator to ``fogiac sweep`` the rest. With the
state in a shared bucket, Pulumi's checkpoints are there (``<prefix>/.pulumi/stacks/``), not in the member's
stack folder: a second member (an empty home and state folder, the same ``FOGIAC_STATE_URL``) must read them
from the bucket. Two stacks, each with a checkpoint as Pulumi's file backend writes it, and a VPC per stack
in LocalStack's EC2; a VPC no checkpoint names is still reported.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import Any

import pytest

from fogiac.targets.aws import api
from fogiac.targets.aws.engine import known_ids
from stacks.aws import PROJECT

pytestmark = pytest.mark.localstack


def _checkpoint(stack: str, vpc: str) -> bytes:
    """A Pulumi DIY-backend checkpoint (version 3) of a network layer holding ``vpc``."""
    urn = f"urn:pulumi:{stack}::{PROJECT}::aws:ec2/vpc:Vpc::vpc"
    return json.dumps({"version": 3, "checkpoint": {"stack": stack, "latest": {"resources": [
        {"urn": f"urn:pulumi:{stack}::{PROJECT}::pulumi:pulumi:Stack::{PROJECT}-{stack}", "custom": False,
         "type": "pulumi:pulumi:Stack"},
        {"urn": urn, "custom": True, "id": vpc, "type": "aws:ec2/vpc:Vpc",
         "outputs": {"id": vpc, "cidrBlock": "10.0.0.0/16", "tags": {api.STACK_TAG: stack}}},
    ]}}}).encode()


def _vpc(ec2: Any, stack: str) -> str:
    return str(ec2.create_vpc(CidrBlock="10.0.0.0/16", TagSpecifications=[
        {"ResourceType": "vpc", "Tags": [{"Key": api.STACK_TAG, "Value": stack}]}])["Vpc"]["VpcId"])


def test_a_second_member_knows_every_stack_in_the_bucket_and_sees_no_strangers(
        ec2: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import boto3

    bucket = f"fogiac-known-{uuid.uuid4().hex[:10]}"
    s3 = boto3.client("s3")
    s3.create_bucket(Bucket=bucket, CreateBucketConfiguration={"LocationConstraint": "us-west-2"})
    stacks = [f"alpha{uuid.uuid4().hex[:6]}-dev", f"beta{uuid.uuid4().hex[:6]}-dev"]
    vpcs = {stack: _vpc(ec2, stack) for stack in stacks}
    for stack, vpc in vpcs.items():  # each stack's network layer, as the member who applied it left it
        s3.put_object(Bucket=bucket, Key=f"lab/.pulumi/stacks/{PROJECT}/{stack}-network.json",
                      Body=_checkpoint(f"{stack}-network", vpc))
        s3.put_object(Bucket=bucket, Key=f"lab/{stack}/record.json", Body=json.dumps(
            {"serial": 1, "deployment": {"target": "aws", "state": "complete"}}).encode())
    stranger = _vpc(ec2, stacks[0])  # tagged like the stack, in no checkpoint: left by something else

    # another member's machine: nothing of either stack on its disk
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    monkeypatch.setenv("FOGIAC_STATE_PASSPHRASE", "the lab's passphrase")
    monkeypatch.setenv("FOGIAC_STATE_URL", f"s3://{bucket}/lab")
    for stack, vpc in vpcs.items():
        known = known_ids(stack)
        assert vpc in known, (stack, sorted(known))
        assert stranger not in known
    assert api.conflicts(ec2, stacks[1], known_ids=known_ids(stacks[1])) == []
    assert api.conflicts(ec2, stacks[0], known_ids=known_ids(stacks[0])) == [stranger]

    # the folder store still reads only the stack folder's own backend: nothing of the bucket
    monkeypatch.delenv("FOGIAC_STATE_URL")
    assert vpcs[stacks[0]] not in known_ids(stacks[0])
