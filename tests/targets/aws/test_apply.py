"""The compiled stacks applied to LocalStack through the harness: what exists is what was planned.

The Pulumi engine cannot run here, so the stack programs run under Pulumi's mock runtime and the
harness creates each declared resource through boto3 (see harness.py). Client VPN, which
LocalStack lacks, is checked on what the harness recorded.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from fogiac.targets.aws.api import preflight, status
from fogiac.targets.aws.sweep import sweep
from fogiac.certs import new_bundle
from fogiac.plan.model import OPERATOR, Plan

from .conftest import NEWEST_UBUNTU, REGION
from .harness import CLIENT_VPN, Harness, InjectedFailure
from .plans import make_plan

pytestmark = pytest.mark.localstack
PUBLIC_KEY = "ssh-ed25519 AAAAC3NzaC1lZDI1NTE5AAAAIHn2fH5hLQm0qR0e6d1W8bUu0fU0n6cJzqXQ2wV0g3pF fogiac-test"


def _tags(item: dict[str, Any]) -> dict[str, str]:
    return {t["Key"]: t["Value"] for t in item.get("Tags", [])}


def _stack_filter(plan: Plan) -> list[dict[str, Any]]:
    return [{"Name": "tag:fogiac:stack", "Values": [plan.stack]}]


def _expected_rules(plan: Plan, cidrs: tuple[str, ...]) -> dict[str, set[tuple[Any, ...]]]:
    out: dict[str, set[tuple[Any, ...]]] = {}
    for group in plan.security_groups:
        rules = set()
        for egress, listed in ((False, group.ingress), (True, group.egress)):
            for r in listed:
                for cidr in cidrs if r.cidr == OPERATOR else (r.cidr,):
                    ports = (None, None) if r.protocol == "-1" else (r.from_port, r.to_port)
                    rules.add((egress, r.protocol, *ports, cidr, r.description))
        out[group.name] = rules
    return out


def _actual_rules(ec2: Any, group_id: str) -> set[tuple[Any, ...]]:
    rules = ec2.describe_security_group_rules(Filters=[{"Name": "group-id", "Values": [group_id]}])
    return {(r["IsEgress"], r["IpProtocol"],
             *((None, None) if r["IpProtocol"] == "-1" else (r["FromPort"], r["ToPort"])),
             r["CidrIpv4"], r.get("Description", "")) for r in rules["SecurityGroupRules"]}


def _inventory(ec2: Any, acm: Any, plan: Plan, logs: Any = None, iam: Any = None) -> set[str]:
    from fogiac.targets.aws.sweep import inventory

    return {f.id for f in inventory(plan.stack, ec2=ec2, acm=acm, logs=logs, iam=iam)[0]}


def test_apply_matches_plan_reapply_creates_nothing_down_leaves_nothing(ec2: Any, acm: Any, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "apply", nodes=(("planner", "c5.large"), ("grasp", "g5.xlarge")))
    report = preflight(plan, ec2=ec2)
    harness = Harness(ec2=ec2, acm=acm, path=tmp_path / "harness-state.json")
    out = harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=report.operator_cidrs,
                        public_key_openssh=PUBLIC_KEY)
    net, hosts = out["network"], out["compute"]["hosts"]
    assert plan.network is not None

    vpc = ec2.describe_vpcs(VpcIds=[net["vpc_id"]])["Vpcs"][0]
    assert vpc["CidrBlock"] == plan.network.vpc_cidr
    assert _tags(vpc) == {**dict(plan.tags), "Name": f"{plan.stack}-vpc"}
    for spec in plan.network.subnets:
        subnet = ec2.describe_subnets(SubnetIds=[net["subnet_ids"][spec.name]])["Subnets"][0]
        assert (subnet["CidrBlock"], subnet["AvailabilityZone"], subnet["MapPublicIpOnLaunch"], subnet["VpcId"]) == (
            spec.cidr, report.zone, False, vpc["VpcId"])  # each instance asks for its own public address
        table = ec2.describe_route_tables(Filters=[{"Name": "association.subnet-id", "Values": [subnet["SubnetId"]]}])
        routes = {r.get("DestinationCidrBlock"): r.get("GatewayId") for r in table["RouteTables"][0]["Routes"]}
        assert ("0.0.0.0/0" in routes) == spec.public, routes
        if spec.public:
            assert routes["0.0.0.0/0"].startswith("igw-")
            gw = ec2.describe_internet_gateways(InternetGatewayIds=[routes["0.0.0.0/0"]])["InternetGateways"][0]
            assert gw["Attachments"][0]["VpcId"] == vpc["VpcId"]

    expected = _expected_rules(plan, report.operator_cidrs)
    assert set(net["security_group_ids"]) == set(expected)
    for name, gid in net["security_group_ids"].items():
        assert _actual_rules(ec2, gid) == expected[name], name

    for host in plan.hosts:
        inst = ec2.describe_instances(InstanceIds=[hosts[host.name]["instance_id"]])["Reservations"][0]["Instances"][0]
        assert inst["InstanceType"] == host.machine
        assert inst["SubnetId"] == net["subnet_ids"]["hosts"]
        assert [g["GroupId"] for g in inst["SecurityGroups"]] == [net["security_group_ids"]["hosts"]]
        assert inst["KeyName"] == f"fogiac-{plan.stack}"
        assert inst["MetadataOptions"]["HttpTokens"] == "required"
        assert inst["EbsOptimized"] is True
        assert _tags(inst) == dict(host.tags)
        assert inst["ImageId"] == (report.image(host.name))
        assert hosts[host.name]["private_ip"] == inst["PrivateIpAddress"]
    assert report.image("planner") == NEWEST_UBUNTU

    certs = {c["CertificateArn"] for c in acm.list_certificates()["CertificateSummaryList"]}
    vpn = harness.client_vpn()
    endpoint = vpn[CLIENT_VPN[0]]
    assert plan.vpn is not None
    assert endpoint["serverCertificateArn"] in certs
    assert endpoint["authenticationOptions"][0]["rootCertificateChainArn"] in certs
    assert endpoint["securityGroupIds"] == [net["security_group_ids"]["vpn"]]
    assert (endpoint["clientCidrBlock"], endpoint["splitTunnel"], endpoint["vpcId"]) == (
        plan.vpn.client_cidr, True, vpc["VpcId"])
    assert vpn[CLIENT_VPN[1]]["subnetId"] == net["subnet_ids"]["vpn"]
    assert vpn[CLIENT_VPN[1]]["clientVpnEndpointId"] == endpoint["id"] == net["vpn_endpoint_id"]
    assert vpn[CLIENT_VPN[2]]["targetNetworkCidr"] == plan.network.vpc_cidr

    rows = status(plan.stack, region=REGION, ec2=ec2)
    assert [(r.name, r.machine, r.state) for r in rows] == [("grasp", "g5.xlarge", "running"),
                                                             ("planner", "c5.large", "running")]
    assert all(r.private_ip and r.cost_usd >= 0 for r in rows)

    before = _inventory(ec2, acm, plan)
    again = Harness(ec2=ec2, acm=acm, path=tmp_path / "harness-state.json")
    assert again.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=report.operator_cidrs,
                       public_key_openssh=PUBLIC_KEY) == out
    assert again.created == [] and len(again.reused) == len(harness.created)
    assert _inventory(ec2, acm, plan) == before

    assert again.destroy() == []
    assert again.state == {}
    assert _inventory(ec2, acm, plan, again.logs, again.iam) == set()
    assert sweep(plan.stack, dry_run=True, ec2=ec2, acm=acm).found == ()


@pytest.mark.parametrize("fail_at", [3, 12, 22])
def test_failed_apply_then_down_leaves_nothing(ec2: Any, acm: Any, tmp_path: Path, fail_at: int) -> None:
    plan = make_plan(tmp_path, f"broken{fail_at}", nodes=(("planner", "c5.large"),))
    harness = Harness(ec2=ec2, acm=acm, fail_at=fail_at)
    with pytest.raises(InjectedFailure, match=rf"^injected failure at resource {fail_at}: "):
        harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                      public_key_openssh=PUBLIC_KEY)
    assert len(harness.created) == fail_at - 1
    assert ec2.describe_vpcs(Filters=_stack_filter(plan))["Vpcs"], "the failed apply left a VPC to clean up"
    # down: destroy what the state knows (past errors), then sweep what it does not.
    harness.destroy()
    result = sweep(plan.stack, dry_run=False, ec2=ec2, acm=acm, first_delay_s=0.1)
    assert result.left == ()
    assert _inventory(ec2, acm, plan) == set()


def test_flow_logs_default_group_and_vpn_logs_apply_and_down_leaves_none(
        ec2: Any, acm: Any, logs: Any, iam: Any, tmp_path: Path) -> None:
    """The posture resources: the VPC's default group without rules, flow logs to a log group through a role
    of the stack, the Client VPN's log group; destroy leaves none of them (the default group goes with the VPC)."""
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    from .plans import manifest_text

    path = tmp_path / "flows.yaml"
    path.write_text(manifest_text("flows").replace("  mode: vpn\n", "  mode: vpn\n  flow_logs: true\n"))
    plan = compile_plan(load_manifest(path))
    harness = Harness(ec2=ec2, acm=acm, logs=logs, iam=iam)
    out = harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                        public_key_openssh=PUBLIC_KEY)
    vpc = out["network"]["vpc_id"]
    (default,) = ec2.describe_security_groups(Filters=[{"Name": "vpc-id", "Values": [vpc]},
                                                       {"Name": "group-name", "Values": ["default"]}])["SecurityGroups"]
    assert default["IpPermissions"] == [] and default["IpPermissionsEgress"] == []
    assert _tags(default)["fogiac:stack"] == plan.stack
    (flow,) = ec2.describe_flow_logs(Filters=[{"Name": "resource-id", "Values": [vpc]}])["FlowLogs"]
    groups = {g["logGroupName"]: g for g in logs.describe_log_groups(logGroupNamePrefix=f"/fogiac/{plan.stack}/")[
        "logGroups"]}
    assert set(groups) == {f"/fogiac/{plan.stack}/flow-logs", f"/fogiac/{plan.stack}/client-vpn"}
    assert {g["retentionInDays"] for g in groups.values()} == {365}
    assert flow["TrafficType"] == "ALL" and flow["LogDestinationType"] == "cloud-watch-logs"
    (role,) = iam.list_roles(PathPrefix=f"/fogiac/{plan.stack}/")["Roles"]
    assert flow["DeliverLogsPermissionArn"] == role["Arn"]
    assert iam.list_role_policies(RoleName=role["RoleName"])["PolicyNames"] == ["write-flow-logs"]
    endpoint = harness.client_vpn()[CLIENT_VPN[0]]
    assert endpoint["connectionLogOptions"] == {"enabled": True, "cloudwatchLogGroup": f"/fogiac/{plan.stack}/client-vpn"}
    found = _inventory(ec2, acm, plan, logs, iam)
    assert {flow["FlowLogId"], role["RoleName"], *groups} <= found
    assert default["GroupId"] not in found  # sweep never touches the default group: AWS deletes it with the VPC

    assert harness.destroy() == []
    assert _inventory(ec2, acm, plan, logs, iam) == set()
    assert ec2.describe_security_groups(Filters=[{"Name": "vpc-id", "Values": [vpc]}])["SecurityGroups"] == []
    assert sweep(plan.stack, dry_run=True, ec2=ec2, acm=acm, logs=logs, iam=iam).found == ()


def test_sweep_removes_flow_logs_a_failed_apply_left(ec2: Any, acm: Any, logs: Any, iam: Any, tmp_path: Path) -> None:
    """An apply that fails after the flow log is made: down's sweep finds and removes every piece."""
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    from .plans import manifest_text

    path = tmp_path / "flowfail.yaml"
    path.write_text(manifest_text("flowfail").replace("  mode: vpn\n", "  mode: proxy\n  flow_logs: true\n"))
    plan = compile_plan(load_manifest(path))
    harness = Harness(ec2=ec2, acm=acm, logs=logs, iam=iam, fail_at=14)
    with pytest.raises(InjectedFailure):
        harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                      public_key_openssh=PUBLIC_KEY)
    assert any(key.endswith("aws:ec2/flowLog:FlowLog/flowfail-dev-flow-log") for key in harness.created)
    result = sweep(plan.stack, dry_run=False, ec2=ec2, acm=acm, logs=logs, iam=iam, first_delay_s=0.1)
    assert result.left == () and {f.kind for f in result.deleted} >= {"flow-log", "log-group", "iam-role", "vpc"}
    assert _inventory(ec2, acm, plan, logs, iam) == set()
