"""Network: the VPC, its two subnets, the internet gateway and the routes.

The hosts subnet is public (instances get a public address for SSH and, in proxy mode, the
relay); the Client VPN target subnet is private and routes only inside the VPC, because the
edge reaches nothing but the VPC over the VPN (split tunnel).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import pulumi
import pulumi_aws as aws

from fogiac.plan.model import NetworkSpec
from stacks.tags import tagged

_ANYWHERE = "0.0.0.0/0"  # the public route table's default route (egress, not a firewall rule)


@dataclass(frozen=True)
class NetworkArgs:
    spec: NetworkSpec
    zone: str
    tags: Mapping[str, str]


class Network(pulumi.ComponentResource):
    """A VPC with one public and one private subnet in ``zone``."""

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
        self.subnets = {
            subnet.name: aws.ec2.Subnet(
                f"{name}-subnet-{subnet.name}",
                vpc_id=self.vpc.id,
                cidr_block=subnet.cidr,
                availability_zone=args.zone,
                map_public_ip_on_launch=subnet.public,
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
        self.register_outputs(
            {
                "vpc_id": self.vpc.id,
                "subnet_ids": {key: subnet.id for key, subnet in self.subnets.items()},
            }
        )
