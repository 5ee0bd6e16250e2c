"""The aws target's own part of the Plan: its Client VPN endpoint and its AMI queries.

The provider-neutral Plan holds them as :class:`fogiac.plan.model.EdgeVpn` and
:class:`fogiac.plan.model.MachineImage`; the plan document and digest serialise them as before
(``dataclasses.asdict``). The stack programs (``stacks/``) and the boto3 checks read them here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from fogiac.plan.model import HostSpec, Plan


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
