"""The aws target's own part of the Plan: its VPC and subnets, its Client VPN endpoint and its AMI queries.

The provider-neutral Plan holds them as :class:`fogiac.plan.model.NetworkSpec`,
:class:`fogiac.plan.model.EdgeVpn` and :class:`fogiac.plan.model.MachineImage`; the plan document and
digest serialise them as before (``dataclasses.asdict``). The stack programs (``stacks/aws/``) and the
boto3 checks read them here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from fogiac.plan.model import HostSpec, Plan

SubnetRole = Literal["instances", "vpn"]


@dataclass(frozen=True)
class Subnet:
    name: str
    cidr: str
    role: SubnetRole  # "instances" (public, the hosts) or "vpn" (Client VPN target)
    public: bool
    zone: str | None = None  # None: the plan's zone; a replicated node's hosts have subnets in zones of their own


@dataclass(frozen=True)
class VpcSpec:
    """The stack's VPC (:class:`fogiac.plan.model.NetworkSpec`): its range, its subnets, its flow logs."""

    vpc_cidr: str
    subnets: tuple[Subnet, ...]
    flow_logs: bool = False  # VPC flow logs to a CloudWatch log group of the stack

    def document(self, fields: dict[str, Any]) -> dict[str, Any]:
        """A subnet in the plan's zone has no ``zone`` key: plans from before replicas keep their bytes
        (and digests)."""
        for subnet in fields["subnets"]:
            if subnet["zone"] is None:
                del subnet["zone"]
        return fields


@dataclass(frozen=True)
class VpnSpec:
    client_cidr: str
    server_name: str
    target_subnet: str
    authorize_cidr: str
    split_tunnel: bool = True
    transport: Literal["udp", "tcp"] = "udp"
    port: int = 443

    @property
    def label(self) -> str:
        return "AWS Client VPN"


@dataclass(frozen=True)
class ImageQuery:
    """How Compute finds its AMI: owner and name pattern, newest first."""

    owners: tuple[str, ...]
    name_pattern: str
    description: str


def vpc_of(plan: Plan) -> VpcSpec | None:
    """The plan's VPC, as the aws placement made it."""
    assert plan.network is None or isinstance(plan.network, VpcSpec), plan.network
    return plan.network


def vpn_of(plan: Plan) -> VpnSpec | None:
    """The plan's Client VPN, as the aws placement made it."""
    assert plan.vpn is None or isinstance(plan.vpn, VpnSpec), plan.vpn
    return plan.vpn


def image_of(host: HostSpec) -> ImageQuery | None:
    """The host's AMI query, as the aws placement made it."""
    assert host.image is None or isinstance(host.image, ImageQuery), host.image
    return host.image


def zone_subnet(zone: str) -> str:
    """The subnet of a replica's host in ``zone`` (every other host's is ``hosts``, in the plan's zone)."""
    return f"hosts-{zone}"
