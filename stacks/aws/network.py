"""Network: the VPC, its two subnets, the internet gateway and the routes.

The hosts subnet is public (each instance asks for a public address for SSH and, in proxy mode,
the relay; the subnet itself maps none on launch); the Client VPN target subnet is private and
routes only inside the VPC, because the edge reaches nothing but the VPC over the VPN (split
tunnel). The VPC's default security group is adopted and left without rules: fogiac never uses
it, so nothing launched into the VPC without a group can talk. With ``flow_logs`` the VPC's
traffic is logged to a CloudWatch log group of the stack, written through a role of its own.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

import pulumi
import pulumi_aws as aws

from fogiac.targets.aws.model import VpcSpec
from stacks.aws.tags import tagged

_ANYWHERE = "0.0.0.0/0"  # the public route table's default route (egress, not a firewall rule)
LOG_RETENTION_DAYS = 365  # a year, as scanners ask; the group goes with the stack at down anyway


def log_group_name(stack: str, what: str) -> str:
    """Every log group of a stack sits under ``/fogiac/<stack>/``, so sweep finds them by prefix."""
    return f"/fogiac/{stack}/{what}"


def log_group(name: str, logical: str, group: str, *, tags: Mapping[str, str],
              opts: pulumi.ResourceOptions) -> aws.cloudwatch.LogGroup:
    """One of the stack's log groups (flow logs, Client VPN connections): ``{name}-{logical}`` to Pulumi,
    ``/fogiac/{name}/{group}`` to AWS, kept LOG_RETENTION_DAYS, tagged like every resource of the stack."""
    return aws.cloudwatch.LogGroup(f"{name}-{logical}", name=log_group_name(name, group),
                                   retention_in_days=LOG_RETENTION_DAYS, tags=tagged(tags, f"{name}-{logical}"),
                                   opts=opts)


BOUNDARY_POLICY = "fogiac-boundary"  # the permissions boundary every role fogiac makes carries (iam-boundary.json)


def boundary_arn(account: str) -> str:
    """The account's ``fogiac-boundary`` policy: the shipped IAM policy lets fogiac create a role only with it,
    so no role fogiac makes can hold more than writing the stack's logs, whatever its inline policy says."""
    return f"arn:aws:iam::{account}:policy/{BOUNDARY_POLICY}"


def flow_logs_role_name(stack: str) -> str:
    return f"fogiac-{stack}-flow-logs"[:64]


def _assume_role(service: str) -> str:
    return json.dumps({"Version": "2012-10-17", "Statement": [
        {"Effect": "Allow", "Principal": {"Service": service}, "Action": "sts:AssumeRole"}]})


def _write_logs(log_group_arn: str) -> str:
    return json.dumps({"Version": "2012-10-17", "Statement": [
        {"Effect": "Allow", "Action": ["logs:CreateLogStream", "logs:PutLogEvents", "logs:DescribeLogGroups",
                                       "logs:DescribeLogStreams"],
         "Resource": [log_group_arn, f"{log_group_arn}:*"]}]})


@dataclass(frozen=True)
class NetworkArgs:
    spec: VpcSpec
    zone: str
    tags: Mapping[str, str]


class Network(pulumi.ComponentResource):
    """A VPC with one public and one private subnet in ``zone`` (and a public one in each zone a replicated
    node's hosts use)."""

    vpc: aws.ec2.Vpc
    subnets: dict[str, aws.ec2.Subnet]

    def __init__(self, name: str, args: NetworkArgs, opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__("fogiac:aws:Network", name, None, opts)
        child = pulumi.ResourceOptions(parent=self)
        self.vpc = aws.ec2.Vpc(
            f"{name}-vpc",
            cidr_block=args.spec.vpc_cidr,
            enable_dns_support=True,
            enable_dns_hostnames=True,
            tags=tagged(args.tags, f"{name}-vpc"),
            opts=child,
        )
        self.internet_gateway = aws.ec2.InternetGateway(
            f"{name}-igw", vpc_id=self.vpc.id, tags=tagged(args.tags, f"{name}-igw"), opts=child
        )
        self.default_group = aws.ec2.DefaultSecurityGroup(  # no ingress, no egress: every rule removed
            f"{name}-default-sg", vpc_id=self.vpc.id, tags=tagged(args.tags, f"{name}-default"), opts=child
        )
        self.subnets = {
            subnet.name: aws.ec2.Subnet(
                f"{name}-subnet-{subnet.name}",
                vpc_id=self.vpc.id,
                cidr_block=subnet.cidr,
                availability_zone=subnet.zone or args.zone,  # a replica's subnet is in its own zone
                map_public_ip_on_launch=False,  # each instance asks for its own public address
                tags=tagged(args.tags, f"{name}-{subnet.name}"),
                opts=child,
            )
            for subnet in args.spec.subnets
        }
        self.public_routes = aws.ec2.RouteTable(
            f"{name}-rt-public",
            vpc_id=self.vpc.id,
            routes=[aws.ec2.RouteTableRouteArgs(cidr_block=_ANYWHERE, gateway_id=self.internet_gateway.id)],
            tags=tagged(args.tags, f"{name}-public"),
            opts=child,
        )
        self.private_routes = aws.ec2.RouteTable(
            f"{name}-rt-private", vpc_id=self.vpc.id, tags=tagged(args.tags, f"{name}-private"), opts=child
        )
        self.associations = [
            aws.ec2.RouteTableAssociation(
                f"{name}-rta-{subnet.name}",
                subnet_id=self.subnets[subnet.name].id,
                route_table_id=(self.public_routes if subnet.public else self.private_routes).id,
                opts=child,
            )
            for subnet in args.spec.subnets
        ]
        self.flow_log: aws.ec2.FlowLog | None = None
        if args.spec.flow_logs:
            self._flow_logs(name, args, child)
        self.register_outputs(
            {
                "vpc_id": self.vpc.id,
                "subnet_ids": {key: subnet.id for key, subnet in self.subnets.items()},
            }
        )

    def _flow_logs(self, name: str, args: NetworkArgs, child: pulumi.ResourceOptions) -> None:
        self.flow_log_group = log_group(name, "flow-logs", "flow-logs", tags=args.tags, opts=child)
        self.flow_log_role = aws.iam.Role(
            f"{name}-flow-logs-role",
            name=flow_logs_role_name(name),
            path=f"/fogiac/{name}/",
            assume_role_policy=_assume_role("vpc-flow-logs.amazonaws.com"),
            permissions_boundary=aws.get_caller_identity_output(opts=pulumi.InvokeOutputOptions(parent=self))
            .account_id.apply(boundary_arn),
            tags=tagged(args.tags, f"{name}-flow-logs"),
            opts=child,
        )
        self.flow_log_policy = aws.iam.RolePolicy(
            f"{name}-flow-logs-policy",
            name="write-flow-logs",
            role=self.flow_log_role.id,
            policy=self.flow_log_group.arn.apply(_write_logs),
            opts=child,
        )
        self.flow_log = aws.ec2.FlowLog(
            f"{name}-flow-log",
            vpc_id=self.vpc.id,
            traffic_type="ALL",
            log_destination_type="cloud-watch-logs",
            log_destination=self.flow_log_group.arn,
            iam_role_arn=self.flow_log_role.arn,
            tags=tagged(args.tags, f"{name}-flow-log"),
            opts=child,
        )
