"""Drift against LocalStack: apply, change the cloud behind fogiac's back with boto3, refresh, plan.

The apply and the engine's refresh go through the harness (no Pulumi CLI here, as in
test_deploy); what the cloud reports comes from fogiac's own EC2 calls against LocalStack.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fogiac.plan.drift import REFRESHED_FILE
from fogiac.state import stack_dir
from fogiac.targets.aws.engine import OUTPUTS_FILE

from .harness import Harness
from .plans import write_manifest
from .test_deploy import down, engine_is_harness, fogiac  # noqa: F401 (the fixture)

pytestmark = pytest.mark.localstack


def _hosts_group(ec2: Any, stack: str) -> str:
    groups = ec2.describe_security_groups(Filters=[{"Name": "tag:fogiac:stack", "Values": [stack]},
                                                   {"Name": "group-name", "Values": [f"fogiac-{stack}-hosts"]}])
    return str(groups["SecurityGroups"][0]["GroupId"])


def test_refresh_then_plan_shows_what_changed_outside_fogiac(engine_is_harness: Harness, ec2: Any,  # noqa: F811
                                                              tmp_path: Path) -> None:
    path = write_manifest(tmp_path, "drifted", nodes=(("planner", "c5.large"),))
    assert fogiac("up", str(path), "--yes", "--infra-only").exit_code == 0
    folder = stack_dir("drifted-dev")
    instance = json.loads((folder / OUTPUTS_FILE).read_text())["compute"]["hosts"]["planner"]["instance_id"]

    clean = fogiac("refresh", str(path))
    assert clean.exit_code == 0, clean.output
    # The hosts' and the VPN's groups, and the VPC's default group fogiac adopted (and emptied).
    assert "cloud: 1 instance(s) and 3 security group(s) as AWS reports them; no drift from what was applied" \
        in clean.stdout.splitlines()
    unchanged = fogiac("plan", str(path), "--detailed-exitcode")
    assert unchanged.exit_code == 0, unchanged.output
    assert "No changes." in unchanged.stdout

    # Out of band, as someone in the console would: a bigger type, and a port opened to the world.
    ec2.stop_instances(InstanceIds=[instance])
    ec2.modify_instance_attribute(InstanceId=instance, InstanceType={"Value": "c5.xlarge"})
    ec2.start_instances(InstanceIds=[instance])
    group = _hosts_group(ec2, "drifted-dev")
    added = ec2.authorize_security_group_ingress(GroupId=group, IpPermissions=[
        {"IpProtocol": "tcp", "FromPort": 5432, "ToPort": 5432, "IpRanges": [{"CidrIp": "0.0.0.0/0"}]}])
    rule = added["SecurityGroupRules"][0]["SecurityGroupRuleId"]

    refreshed = fogiac("refresh", str(path))
    assert refreshed.exit_code == 0, refreshed.output
    assert (f"cloud: 1 instance(s) and 3 security group(s) as AWS reports them; 2 drifted: drifted-dev-host-planner "
            f"(changed outside fogiac), {rule} (made outside fogiac); `fogiac plan` shows how") \
        in refreshed.stdout.splitlines()
    drifted = fogiac("plan", str(path), "--detailed-exitcode")
    assert drifted.exit_code == 2, drifted.output
    lines = [line.strip() for line in drifted.stdout.splitlines()]
    assert "! aws:ec2/instance:Instance drifted-dev-host-planner changed outside fogiac" in lines
    assert "instanceType: c5.large (applied) -> c5.xlarge (cloud)" in lines
    opened = "fogiac-drifted-dev-hosts tcp port 5432 from 0.0.0.0/0"
    assert f"!+ aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule {rule} made outside fogiac: {opened}" \
        in lines
    assert f"! ingress added outside fogiac: {opened}" in lines  # a widened exposure, flagged first
    assert lines[-1] == "Plan: 0 to add, 0 to change, 0 to destroy. Drift: 1 changed, 1 added outside fogiac."
    doc = json.loads(fogiac("plan", str(path), "--json").stdout)
    assert [(d["name"], d["status"]) for d in doc["changes"]["drift"]] == [
        ("drifted-dev-host-planner", "changed"), (rule, "added")]

    # The instance deleted out of band, the rule taken back: refresh sees exactly that.
    ec2.revoke_security_group_ingress(GroupId=group, SecurityGroupRuleIds=[rule])
    ec2.terminate_instances(InstanceIds=[instance])
    assert fogiac("refresh", str(path)).exit_code == 0
    gone = fogiac("plan", str(path), "--detailed-exitcode")
    assert gone.exit_code == 2, gone.output
    lines = [line.strip() for line in gone.stdout.splitlines()]
    assert "x aws:ec2/instance:Instance drifted-dev-host-planner deleted outside fogiac" in lines
    assert lines[-1] == "Plan: 0 to add, 0 to change, 0 to destroy. Drift: 1 deleted outside fogiac."

    # A rule added to the VPC's default group (fogiac adopted it with none) is drift and widened exposure too.
    (default,) = ec2.describe_security_groups(Filters=[{"Name": "tag:fogiac:stack", "Values": ["drifted-dev"]},
                                                       {"Name": "group-name", "Values": ["default"]}])["SecurityGroups"]
    opened_default = ec2.authorize_security_group_ingress(GroupId=default["GroupId"], IpPermissions=[
        {"IpProtocol": "tcp", "FromPort": 22, "ToPort": 22, "IpRanges": [{"CidrIp": "0.0.0.0/0"}]}])
    default_rule = opened_default["SecurityGroupRules"][0]["SecurityGroupRuleId"]
    assert fogiac("refresh", str(path)).exit_code == 0
    lines = [line.strip() for line in fogiac("plan", str(path)).stdout.splitlines()]
    assert "! ingress added outside fogiac: default tcp port 22 from 0.0.0.0/0" in lines
    assert f"!+ aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule {default_rule} made outside fogiac: " \
        "default tcp port 22 from 0.0.0.0/0" in lines

    assert down(str(path), "--yes").exit_code == 0
    assert not (folder / REFRESHED_FILE).exists()


def test_an_apply_drops_the_last_refresh(engine_is_harness: Harness, ec2: Any, tmp_path: Path) -> None:  # noqa: F811
    """After up, the recorded refresh describes a cloud that no longer is: plan stops showing its drift."""
    path = write_manifest(tmp_path, "redone", nodes=(("planner", "c5.large"),))
    assert fogiac("up", str(path), "--yes", "--infra-only").exit_code == 0
    group = _hosts_group(ec2, "redone-dev")
    ec2.authorize_security_group_ingress(GroupId=group, IpPermissions=[
        {"IpProtocol": "tcp", "FromPort": 8080, "ToPort": 8080, "IpRanges": [{"CidrIp": "10.10.0.0/16"}]}])
    assert fogiac("refresh", str(path)).exit_code == 0
    assert fogiac("plan", str(path), "--detailed-exitcode").exit_code == 2
    assert fogiac("up", str(path), "--yes", "--infra-only").exit_code == 0
    assert not (stack_dir("redone-dev") / REFRESHED_FILE).exists()
    assert fogiac("plan", str(path), "--detailed-exitcode").exit_code == 0
    assert down(str(path), "--yes").exit_code == 0
