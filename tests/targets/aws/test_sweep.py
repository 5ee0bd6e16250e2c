"""sweep removes resources leaked outside any state, in dependency order, and says what it could not check."""

from __future__ import annotations

from typing import Any

import pytest

from fogiac.targets.aws.sweep import sweep
from fogiac.certs import new_bundle
from fogiac.errors import CloudError

from .conftest import NEWEST_UBUNTU, REGION

pytestmark = pytest.mark.localstack


def _tags(stack: str, kind: str) -> list[dict[str, Any]]:
    return [{"ResourceType": kind, "Tags": [{"Key": "fogiac:stack", "Value": stack}]}]


def leak(ec2: Any, acm: Any, stack: str) -> dict[str, str]:
    """Make by hand what a crashed apply could leave: a VPC full of things, a key, an address, a certificate."""
    vpc = ec2.create_vpc(CidrBlock="10.60.0.0/16", TagSpecifications=_tags(stack, "vpc"))["Vpc"]["VpcId"]
    subnet = ec2.create_subnet(VpcId=vpc, CidrBlock="10.60.0.0/24",
                               TagSpecifications=_tags(stack, "subnet"))["Subnet"]["SubnetId"]
    igw = ec2.create_internet_gateway(TagSpecifications=_tags(stack, "internet-gateway"))["InternetGateway"][
        "InternetGatewayId"]
    ec2.attach_internet_gateway(InternetGatewayId=igw, VpcId=vpc)
    table = ec2.create_route_table(VpcId=vpc, TagSpecifications=_tags(stack, "route-table"))["RouteTable"][
        "RouteTableId"]
    ec2.create_route(RouteTableId=table, DestinationCidrBlock="0.0.0.0/0", GatewayId=igw)
    ec2.associate_route_table(RouteTableId=table, SubnetId=subnet)
    groups = [ec2.create_security_group(GroupName=f"{stack}-{n}", Description=n, VpcId=vpc,
                                        TagSpecifications=_tags(stack, "security-group"))["GroupId"]
              for n in ("a", "b")]
    for me, other in (groups, groups[::-1]):  # each group names the other: delete fails until revoked
        ec2.authorize_security_group_ingress(GroupId=me, IpPermissions=[
            {"IpProtocol": "tcp", "FromPort": 22, "ToPort": 22, "UserIdGroupPairs": [{"GroupId": other}]}])
    key = ec2.create_key_pair(KeyName=f"{stack}-key", TagSpecifications=_tags(stack, "key-pair"))["KeyPairId"]
    instance = ec2.run_instances(ImageId=NEWEST_UBUNTU, InstanceType="t3.small", MinCount=1, MaxCount=1,
                                 SubnetId=subnet, SecurityGroupIds=groups,
                                 TagSpecifications=_tags(stack, "instance"))["Instances"][0]["InstanceId"]
    address = ec2.allocate_address(Domain="vpc", TagSpecifications=_tags(stack, "elastic-ip"))["AllocationId"]
    bundle = new_bundle(stack)
    cert = acm.import_certificate(Certificate=bundle.vpn.cert_pem, PrivateKey=bundle.vpn.key_pem,
                                  CertificateChain=bundle.ca.cert_pem,
                                  Tags=[{"Key": "fogiac:stack", "Value": stack}])["CertificateArn"]
    return {"vpc": vpc, "subnet": subnet, "internet-gateway": igw, "route-table": table, "key-pair": key,
            "instance": instance, "elastic-ip": address, "acm-certificate": cert,
            "security-group": ",".join(groups)}


def leak_logs(ec2: Any, logs: Any, iam: Any, stack: str, vpc: str) -> dict[str, str]:
    """What flow logs leave (a log group, a role with an inline policy, the flow log) and the VPN's log group."""
    group = f"/fogiac/{stack}/flow-logs"
    logs.create_log_group(logGroupName=group)
    logs.create_log_group(logGroupName=f"/fogiac/{stack}/client-vpn")
    role = iam.create_role(RoleName=f"fogiac-{stack}-flow-logs", Path=f"/fogiac/{stack}/",
                           AssumeRolePolicyDocument='{"Version": "2012-10-17", "Statement": []}')["Role"]
    iam.put_role_policy(RoleName=role["RoleName"], PolicyName="write", PolicyDocument=(
        '{"Version": "2012-10-17", "Statement": [{"Effect": "Allow", "Action": "logs:PutLogEvents", "Resource": "*"}]}'))
    flow = ec2.create_flow_logs(ResourceIds=[vpc], ResourceType="VPC", TrafficType="ALL",
                                LogDestinationType="cloud-watch-logs", LogGroupName=group,
                                DeliverLogsPermissionArn=role["Arn"], TagSpecifications=_tags(stack, "vpc-flow-log"))
    return {"flow-log": flow["FlowLogIds"][0], "log-group": group, "iam-role": role["RoleName"]}


def test_dry_run_lists_and_deletes_nothing(ec2: Any, acm: Any) -> None:
    made = leak(ec2, acm, "sweep-dry-dev")
    result = sweep("sweep-dry-dev", dry_run=True, ec2=ec2, acm=acm)
    kinds = {f.kind for f in result.found}
    assert kinds >= {"vpc", "subnet", "internet-gateway", "route-table", "security-group", "key-pair",
                     "instance", "elastic-ip", "acm-certificate"}
    assert result.deleted == () and result.left == result.found
    assert ec2.describe_vpcs(VpcIds=[made["vpc"]])["Vpcs"]
    assert sweep("sweep-dry-dev", dry_run=False, ec2=ec2, acm=acm, first_delay_s=0.1).clean


def test_sweep_leaves_nothing_tagged(ec2: Any, acm: Any, logs: Any, iam: Any) -> None:
    made = leak(ec2, acm, "sweep-all-dev")
    made.update(leak_logs(ec2, logs, iam, "sweep-all-dev", made["vpc"]))
    kept = leak_logs(ec2, logs, iam, "sweep-all-dev2", made["vpc"])  # another stack's, by name prefix and path
    other = ec2.create_vpc(CidrBlock="10.61.0.0/16", TagSpecifications=_tags("someone-else", "vpc"))["Vpc"]["VpcId"]
    result = sweep("sweep-all-dev", dry_run=False, ec2=ec2, acm=acm, logs=logs, iam=iam, first_delay_s=0.1)
    assert result.left == () and result.errors == ()
    assert {"/fogiac/sweep-all-dev/flow-logs", "/fogiac/sweep-all-dev/client-vpn", made["iam-role"],
            made["flow-log"]} <= {f.id for f in result.deleted}
    assert logs.describe_log_groups(logGroupNamePrefix="/fogiac/sweep-all-dev/")["logGroups"] == []
    assert iam.list_roles(PathPrefix="/fogiac/sweep-all-dev/")["Roles"] == []
    assert ec2.describe_flow_logs(FlowLogIds=[made["flow-log"]])["FlowLogs"] == []
    assert [g["logGroupName"] for g in logs.describe_log_groups(logGroupNamePrefix="/fogiac/sweep-all-dev2/")[
        "logGroups"]] == ["/fogiac/sweep-all-dev2/client-vpn", "/fogiac/sweep-all-dev2/flow-logs"]
    assert [r["RoleName"] for r in iam.list_roles(PathPrefix="/fogiac/sweep-all-dev2/")["Roles"]] == [kept["iam-role"]]
    assert {f.id for f in result.deleted} >= {v for v in made.values() if "," not in v}
    assert result.not_checked == (
        "client-vpn-endpoint (not supported by this endpoint: InternalFailure)",)
    flt = [{"Name": "tag:fogiac:stack", "Values": ["sweep-all-dev"]}]
    assert ec2.describe_vpcs(Filters=flt)["Vpcs"] == []
    assert ec2.describe_security_groups(Filters=flt)["SecurityGroups"] == []
    assert ec2.describe_key_pairs(Filters=flt)["KeyPairs"] == []
    assert ec2.describe_addresses(Filters=flt)["Addresses"] == []
    states = [i["State"]["Name"] for r in ec2.describe_instances(InstanceIds=[made["instance"]])["Reservations"]
              for i in r["Instances"]]
    assert states in ([], ["terminated"])
    assert made["acm-certificate"] not in {c["CertificateArn"] for c in acm.list_certificates()["CertificateSummaryList"]}
    assert ec2.describe_vpcs(VpcIds=[other])["Vpcs"], "another stack's VPC must survive"
    ec2.delete_vpc(VpcId=other)
    assert sweep("sweep-all-dev2", dry_run=False, ec2=ec2, acm=acm, logs=logs, iam=iam, first_delay_s=0.1).clean


def test_sweep_waits_for_no_one_and_deletes_nothing_while_up_holds_the_lock(
        ec2: Any, acm: Any, tmp_path: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac import targets
    from fogiac.errors import LockHeld
    from fogiac.manifest.schema import parse_manifest
    from fogiac.plan.compile import compile_plan
    from fogiac.state import stack_lock

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    plan = compile_plan(parse_manifest("name: sweeplock\nnodes:\n  - {name: a, machine: t3.micro, image: i}\n"),
                        target="aws")
    made = leak(ec2, acm, plan.stack)  # what a running up is creating
    with stack_lock(plan.stack, operation="up"), pytest.raises(LockHeld, match="is locked by up"):
        targets.get("aws").sweep(plan, dry_run=False)
    assert ec2.describe_vpcs(VpcIds=[made["vpc"]])["Vpcs"]
    assert targets.get("aws").sweep(plan, dry_run=True).deleted == ()  # listing needs no lock
    assert sweep(plan.stack, dry_run=False, ec2=ec2, acm=acm, first_delay_s=0.1).clean


def test_sweep_never_deletes_another_manifests_stack_of_the_same_name(ec2: Any, acm: Any) -> None:
    """Issue 26 item 11: two manifests' stacks named alike (as robot-prod + dev and robot + prod-dev once were)."""
    made = leak(ec2, acm, "robot-prod-dev")
    ec2.create_tags(Resources=[made["vpc"], made["instance"]],
                    Tags=[{"Key": "fogiac:manifest", "Value": "robot-prod"}])
    with pytest.raises(CloudError, match=r"^stack 'robot-prod-dev' in the cloud was made by manifest 'robot-prod', "
                                         r"not 'robot': not deleting"):
        sweep("robot-prod-dev", dry_run=False, ec2=ec2, acm=acm, owner="robot", first_delay_s=0.1)
    assert ec2.describe_vpcs(VpcIds=[made["vpc"]])["Vpcs"]
    assert sweep("robot-prod-dev", dry_run=False, ec2=ec2, acm=acm, owner="robot-prod", first_delay_s=0.1).clean
