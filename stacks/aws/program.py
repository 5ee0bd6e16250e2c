"""The two stack programs, network and compute, built from a compiled Plan.

Both are plain functions run inside a Pulumi program: by ``stacks/aws/__main__.py`` under
``pulumi preview``/``up``, by the engine's Automation API (:mod:`fogiac.pulumi_engine.engine`, fed by
:mod:`fogiac.targets.aws.engine`), or under mocks for the offline plan (:mod:`fogiac.targets.aws.offline`).
Compute takes network's outputs as plain values, so a second ``up`` after ``down --keep-network``
never waits for the slow VPN association again.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pulumi

from fogiac.certs import Bundle
from fogiac.errors import PlanError
from fogiac.plan.model import Plan
from fogiac.targets.aws.model import vpc_of, vpn_of, zone_subnet
from stacks.aws.compute import Compute, ComputeArgs
from stacks.aws.firewall import Firewall, FirewallArgs
from stacks.aws.network import Network, NetworkArgs
from stacks.aws.vpn import ClientVpn, ClientVpnArgs

HOSTS_SUBNET = "hosts"  # the public subnet the instances live in
HOSTS_GROUP = "hosts"  # the instances' security group
VPN_GROUP = "vpn"  # the Client VPN endpoint's security group


def _require_aws(plan: Plan) -> None:
    if plan.network is None:
        raise PlanError(f"target {plan.target!r} has no cloud stacks; only 'aws' does")


def layer_programs(plan: Plan, *, certs: Bundle, operator_cidrs: tuple[str, ...], public_key_openssh: str,
                   network_outputs: Callable[[], Mapping[str, Any]]) -> dict[str, Callable[[], None]]:
    """The program of each layer, network then compute; compute reads the network's outputs when it runs.

    The one place the two stacks are wired together: the engine (outputs of the applied network
    stack), the offline plan (outputs the mocks resolved) and ``stacks/aws/entry.py`` (a
    StackReference) each pass their own ``network_outputs``.
    """
    return {
        "network": lambda: network_program(plan, certs=certs, operator_cidrs=operator_cidrs),
        "compute": lambda: compute_program(plan, network=network_outputs(), public_key_openssh=public_key_openssh),
    }


def network_program(plan: Plan, *, certs: Bundle, operator_cidrs: tuple[str, ...]) -> None:
    """Declare Network, Firewall and (in vpn mode) ClientVpn; export their ids."""
    _require_aws(plan)
    vpc = vpc_of(plan)
    assert vpc is not None
    tags = dict(plan.tags)
    network = Network(plan.stack, NetworkArgs(spec=vpc, zone=plan.zone, tags=tags))
    firewall = Firewall(
        plan.stack,
        FirewallArgs(
            vpc_id=network.vpc.id, groups=plan.security_groups, operator_cidrs=tuple(operator_cidrs), tags=tags
        ),
    )
    pulumi.export("vpc_id", network.vpc.id)
    pulumi.export("subnet_ids", {key: subnet.id for key, subnet in network.subnets.items()})
    pulumi.export("security_group_ids", {key: sg.id for key, sg in firewall.groups.items()})
    spec = vpn_of(plan)
    if spec is not None:
        vpn = ClientVpn(
            plan.stack,
            ClientVpnArgs(
                spec=spec,
                certs=certs,
                vpc_id=network.vpc.id,
                subnet_id=network.subnets[spec.target_subnet].id,
                security_group_id=firewall.groups[VPN_GROUP].id,
                tags=tags,
            ),
        )
        pulumi.export("vpn_endpoint_id", vpn.endpoint.id)
        pulumi.export("vpn_dns_name", vpn.endpoint.dns_name)


def compute_program(plan: Plan, *, network: Mapping[str, Any], public_key_openssh: str) -> None:
    """Declare Compute in the network stack's subnet and security group; export the hosts."""
    _require_aws(plan)
    wanted = [HOSTS_SUBNET] + sorted({zone_subnet(h.zone) for h in plan.hosts if h.zone is not None})
    try:
        subnet_ids = {name: network["subnet_ids"][name] for name in wanted}
        group_id = network["security_group_ids"][HOSTS_GROUP]
    except (KeyError, TypeError):
        raise PlanError(
            f"the network stack of {plan.stack!r} has no outputs subnet_ids.{' / '.join(wanted)} and "
            f"security_group_ids.{HOSTS_GROUP}; apply the network stack first"
        ) from None
    compute = Compute(
        plan.stack,
        ComputeArgs(
            hosts=plan.hosts,
            subnet_id=subnet_ids[HOSTS_SUBNET],
            zone_subnet_ids={h.zone: subnet_ids[zone_subnet(h.zone)] for h in plan.hosts if h.zone is not None},
            security_group_ids=(group_id,),
            public_key_openssh=public_key_openssh,
            tags=dict(plan.tags),
            shutdown_behavior=plan.autostop.action if plan.autostop and plan.autostop.power == "machine" else None,
        ),
    )
    pulumi.export(
        "hosts",
        {
            host.name: {
                "instance_id": compute.instances[host.name].id,
                "public_ip": compute.instances[host.name].public_ip,
                "private_ip": compute.instances[host.name].private_ip,
                "machine": host.machine,
            }
            for host in plan.hosts
        },
    )
