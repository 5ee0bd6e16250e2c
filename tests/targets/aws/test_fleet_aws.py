"""Issue 34 on ``aws``: a robot joins a deployed fleet without a machine, a disk or a security group touched.

Under Pulumi's mock runtime, no emulator: the aws stack programs are what the cloud would be asked for.

- ``fogiac plan`` of the fleet with a third robot, against the record a complete ``up`` of two robots leaves
  (``tests/plan/test_fleet_diff._deploy``): every declared resource, the instances (their root disk among
  their inputs), the security groups and their rules, the Client VPN endpoint, is a no-op, and the diff names
  the robot's certificate, access rules and edge process only. A robot removed deletes nothing.
- The engine's own programs (the stack's real CA, VPN and client certificates, its SSH key: what ``up`` hands
  the Automation API) declare the very same resources, inputs and all, before and after the third robot's
  certificate is issued the way ``up`` issues every robot's (:func:`fogiac.certs.load_or_create_edges`, from
  :func:`fogiac.lifecycle.edge.provision_and_connect`): the robot's pair is its own, kept 0600 beside the
  stack's, and issuing it rotates no certificate AWS holds (which would replace the Client VPN endpoint).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest
from cryptography import x509
from typer.testing import CliRunner

from fogiac.certs import edge_identity, edge_role, load_or_create_edges
from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.pulumi_engine import offline
from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION
from fogiac.state import StackState
from fogiac.targets.aws.engine import Engine, project
from fogiac.targets.aws.offline import PLACEHOLDERS
from tests.plan.test_fleet_diff import AWS, THREE, TWO, _deploy

runner = CliRunner()
STACK = "lab-dev"
INSTANCE, SG = "aws:ec2/instance:Instance", "aws:ec2/securityGroup:SecurityGroup"
UNTOUCHED = (INSTANCE, SG, "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup",
             "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule",
             "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule", "aws:acm/certificate:Certificate",
             "aws:ec2clientvpn/endpoint:Endpoint")


def _on_aws(text: str) -> str:
    return text.replace(*AWS)


def _over_zenoh(text: str) -> str:
    """The same fleet on ROS 2: each robot's edge router on a port of its own instead of its ROS master."""
    text = re.sub(r'ros_master: "http://127.0.0.1:(\d+)"',
                  lambda port: f'zenoh_router: "tcp/127.0.0.1:{int(port[1]) - 11312 + 7447}"', text)
    return text.replace(", compression: zstd", "").replace("cloud:", "ros: {distro: jazzy}\ncloud:", 1)


@pytest.mark.parametrize("over", [_on_aws, lambda text: _over_zenoh(_on_aws(text))], ids=["ros1", "ros2-zenoh"])
def test_a_robot_added_or_removed_on_aws_touches_no_instance_disk_or_security_group(
        tmp_path: Path, over: Callable[[str], str]) -> None:
    manifest = _deploy(tmp_path, over(TWO))
    manifest.write_text(over(THREE))
    shown = runner.invoke(app, ["plan", str(manifest), "--json"])
    assert shown.exit_code == 0, shown.output
    doc = json.loads(shown.output)
    by_type: dict[str, list[dict]] = {}
    for resource in doc["resources"]:
        by_type.setdefault(resource["type"], []).append(resource)
    assert {t: len(by_type.get(t, [])) > 0 for t in UNTOUCHED} == dict.fromkeys(UNTOUCHED, True)  # all declared
    assert all("rootBlockDevice" in r["inputs"] for r in by_type[INSTANCE])  # each instance's disk is an input
    assert {r["action"] for r in doc["resources"]} == {"no-op"}, [
        (r["type"], r["name"], r["action"]) for r in doc["resources"] if r["action"] != "no-op"]
    changes = doc["changes"]
    assert (changes["add"], changes["change"], changes["destroy"]) == (0, 0, 0)
    assert [r["name"] for r in changes["robots"]["added"]] == ["arm3"] and not changes["robots"]["removed"]
    assert changes["hosts"] == {"added": [], "removed": [], "changed": []}
    assert changes["nodes"] == {"added": [], "removed": [], "changed": []}  # (the terminal's lines: test_fleet_diff)

    StackState(STACK).discard()  # the same stack deployed with three robots instead; arm3 leaves
    manifest = _deploy(tmp_path, over(THREE))
    manifest.write_text(over(TWO))
    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    assert {r["action"] for r in doc["resources"]} == {"no-op"}  # nothing deleted with the robot
    assert [r["name"] for r in doc["changes"]["robots"]["removed"]] == ["arm3"]


def _plan(path: Path, text: str) -> Plan:
    path.write_text(_on_aws(text))
    return compile_plan(load_manifest(path))


def _declared(plan: Plan) -> list[tuple[str, str, str, object]]:
    """What ``up`` would hand the engine for ``plan``: the engine's own programs, the stack's real certificates and
    SSH key, run under Pulumi's mock runtime instead of the Automation API."""
    engine = Engine(plan)
    declared = offline.declare(plan, project(plan), lambda earlier: engine.programs(
        operator_cidrs=("203.0.113.7/32",), network_outputs=lambda: earlier("network")), answers=PLACEHOLDERS)
    return [(r.stack, r.type, r.name, r.inputs) for r in declared.resources]


def test_a_robots_certificate_is_its_own_0600_and_rotates_nothing_aws_holds(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bin_dir = tmp_path / "bin"  # the engine checks the Pulumi CLI's version first; nothing reaches it here
    bin_dir.mkdir()
    (bin_dir / "pulumi").write_text(f"#!/bin/sh\necho v{PULUMI_CLI_VERSION}\n")
    (bin_dir / "pulumi").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:/usr/bin:/bin")
    two, three = _plan(tmp_path / "two.yaml", TWO), _plan(tmp_path / "three.yaml", THREE)
    certs = StackState(STACK).certs

    load_or_create_edges(STACK, certs, [edge.named for edge in two.edges])  # the first up: two robots
    before = _declared(two)
    kept = {name: (certs / f"{edge_role(STACK, name)}.pem").read_bytes() for name in ("arm1", "arm2")}
    assert not (certs / f"{edge_role(STACK, 'arm3')}.pem").exists()

    load_or_create_edges(STACK, certs, [edge.named for edge in three.edges])  # arm3 joins: up issues its pair
    key, pem = certs / f"{edge_role(STACK, 'arm3')}.key", certs / f"{edge_role(STACK, 'arm3')}.pem"
    assert key.stat().st_mode & 0o777 == 0o600 and pem.stat().st_mode & 0o022 == 0
    cert = x509.load_pem_x509_certificate(pem.read_bytes())
    ca = x509.load_pem_x509_certificate((certs / "ca.pem").read_bytes())
    cert.verify_directly_issued_by(ca)  # by the stack's CA, which every cloud end trusts
    (name,) = cert.subject.get_attributes_for_oid(x509.NameOID.COMMON_NAME)
    assert name.value == edge_identity(STACK, "arm3")  # the identity each cloud end's access file knows it by
    assert {name: (certs / f"{edge_role(STACK, name)}.pem").read_bytes() for name in kept} == kept  # not reissued

    after = _declared(three)
    assert [r[:3] for r in after] == [r[:3] for r in before]
    assert after == before  # inputs and all: no instance, disk, security group or ACM certificate changes
    assert any(r[1] == INSTANCE for r in after) and any(r[1] == SG for r in after)
