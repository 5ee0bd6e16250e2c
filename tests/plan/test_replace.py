"""The replace-rules table, one test per entry, on the inputs fogiac's stack programs really send.

Each resource comes from an offline plan (the stack programs under Pulumi's mocks); changing an
input the provider marks ForceNew must replace it, changing one it updates in place must not.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from fogiac import targets
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.diff import diff_documents, leaves
from fogiac.plan.document import document
from fogiac.targets.aws.replace import RULES, ReplaceRule, forces_replacement, known_types

MANIFEST = """\
name: rules
cloud: {provider: aws, region: us-west-2}
network: {mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [203.0.113.7/32], flow_logs: true}
nodes:
  - {name: planner, machine: c5.large, image: "ros:noetic-ros-core", spot: true}
"""
IN_PLACE: dict[str, str | None] = {  # an input each type updates in place (None: every input fogiac sends forces new)
    "aws:ec2clientvpn/networkAssociation:NetworkAssociation": None,
    "aws:ec2clientvpn/authorizationRule:AuthorizationRule": None,
    "aws:ec2/internetGateway:InternetGateway": "vpcId",
    "aws:acm/certificate:Certificate": "certificateBody",
    "aws:ec2/instance:Instance": "instanceType",
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": "toPort",
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": "description",
    "aws:ec2clientvpn/endpoint:Endpoint": "splitTunnel",
    "aws:ec2/routeTable:RouteTable": "routes",
    "aws:ec2/routeTableAssociation:RouteTableAssociation": "routeTableId",
    "aws:cloudwatch/logGroup:LogGroup": "retentionInDays",
    "aws:iam/role:Role": "assumeRolePolicy",
    "aws:iam/rolePolicy:RolePolicy": "policy",
}


@pytest.fixture(scope="module")
def doc() -> dict[str, Any]:
    plan = compile_plan(parse_manifest(MANIFEST, base=Path.cwd()), target="aws", environment="dev")
    return document(plan, targets.get("aws").declare(plan), manifest_path="rules.yaml", manifest_sha256="0")


def _set(inputs: dict[str, Any], path: str, value: Any) -> None:
    *parents, last = path.split(".")
    for part in parents:
        inputs = inputs[part]
    inputs[last] = value


def _changed(doc: dict[str, Any], name: str, path: str) -> str:
    after = copy.deepcopy(doc)
    row = next(r for r in after["resources"] if r["name"] == name)
    current = dict(leaves(row["inputs"]))[path]
    _set(row["inputs"], path, (not current) if isinstance(current, bool) else
         current + 1 if isinstance(current, int) else [*current, "x"] if isinstance(current, list) else f"{current}-x")
    return next(r.action for r in diff_documents(doc, after).resources if r.name == name)


@pytest.mark.parametrize("rule", RULES, ids=[r.type for r in RULES])
def test_rule(rule: ReplaceRule, doc: dict[str, Any]) -> None:
    row = next(r for r in doc["resources"] if r["type"] == rule.type)
    paths = dict(leaves(row["inputs"]))
    forced = [p for p in paths if forces_replacement(rule.type, p)]
    assert rule.source.startswith("internal/service/") and rule.source.split(":")[0].endswith(".go")
    assert forced or not rule.forces or rule.type == "aws:ec2/subnet:Subnet", f"no forcing input sent: {paths}"
    for path in forced:
        assert _changed(doc, row["name"], path) == "replace", path
    in_place = IN_PLACE.get(rule.type, "tags.Name")
    if in_place is None:
        assert set(forced) == set(paths)
        return
    assert not forces_replacement(rule.type, in_place)
    assert _changed(doc, row["name"], in_place) == "update"


def test_every_declared_type_has_a_rule(doc: dict[str, Any]) -> None:
    assert sorted({r["type"] for r in doc["resources"]} - set(known_types())) == []


def test_instance_replacements_the_issue_names() -> None:
    instance = "aws:ec2/instance:Instance"
    forced = ("ami", "subnetId", "availabilityZone", "rootBlockDevice.encrypted",
              "instanceMarketOptions.spotOptions.maxPrice")
    assert all(forces_replacement(instance, p) for p in forced)
    assert not any(forces_replacement(instance, p) for p in ("instanceType", "userData", "rootBlockDevice.volumeSize",
                                                             "metadataOptions.httpTokens", "tags.Name"))
    assert forces_replacement("aws:ec2/vpc:Vpc", "cidrBlock") and not forces_replacement("aws:ec2/vpc:Vpc", "tags.Name")
    assert not forces_replacement("aws:unknown/thing:Thing", "anything")
