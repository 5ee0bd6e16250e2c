"""A node with ``replicas: 2`` applied on LocalStack (issue 24): two instances in two zones, each in its
zone's subnet, priced twice; ``down`` (destroy, then the sweep) leaves nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from fogiac.certs import new_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.targets.aws.api import preflight, status
from fogiac.targets.aws.catalog import on_demand
from fogiac.targets.aws.sweep import sweep

from .conftest import REGION
from .harness import Harness
from .plans import manifest_text
from .test_apply import PUBLIC_KEY, _inventory

pytestmark = pytest.mark.localstack


def test_two_replicas_two_zones_applied_and_swept_clean(ec2: Any, acm: Any, tmp_path: Path) -> None:
    path = tmp_path / "replicas.yaml"
    path.write_text(manifest_text("replicas", nodes=(("planner", "c5.large"),), region=REGION) + (
        "    replicas: 2\n    topics: {in: [/plan/request], out: [/plan/path]}\n"
        "    message_types: {/plan/path: geometry_msgs/PoseArray}\n"))
    plan = compile_plan(load_manifest(path))
    assert [(h.name, h.zone) for h in plan.hosts] == [("planner-r1", f"{REGION}a"), ("planner-r2", f"{REGION}b")]
    assert sum(line.total for line in plan.cost if line.item.startswith("instance ")) == \
        pytest.approx(2 * on_demand("c5.large", REGION))
    report = preflight(plan, ec2=ec2)  # the zones exist there and offer c5.large
    harness = Harness(ec2=ec2, acm=acm, path=tmp_path / "harness-state.json")
    out = harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=report.operator_cidrs,
                        public_key_openssh=PUBLIC_KEY)
    net, hosts = out["network"], out["compute"]["hosts"]
    zones = {}
    for host in plan.hosts:
        inst = ec2.describe_instances(InstanceIds=[hosts[host.name]["instance_id"]])["Reservations"][0]["Instances"][0]
        assert inst["SubnetId"] == net["subnet_ids"][f"hosts-{host.zone}"]
        zones[host.name] = inst["Placement"]["AvailabilityZone"]
        subnet = ec2.describe_subnets(SubnetIds=[inst["SubnetId"]])["Subnets"][0]
        assert subnet["AvailabilityZone"] == host.zone
    assert zones == {"planner-r1": f"{REGION}a", "planner-r2": f"{REGION}b"}
    rows = status(plan.stack, region=REGION, ec2=ec2)
    assert sorted((r.name, r.state) for r in rows) == [("planner-r1", "running"), ("planner-r2", "running")]

    assert harness.destroy() == []
    assert _inventory(ec2, acm, plan) == set()
    assert sweep(plan.stack, dry_run=True, ec2=ec2, acm=acm).found == ()
