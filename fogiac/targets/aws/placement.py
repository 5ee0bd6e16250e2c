"""The aws target's part of compile: VPC layout, security groups, Client VPN, images and prices."""

from __future__ import annotations

import dataclasses
import ipaddress
from collections.abc import Mapping

from fogiac.certnames import server_name
from fogiac.errors import FogiacError, PlanError
from fogiac.manifest.machines import MachineSpec
from fogiac.manifest.schema import Manifest
from fogiac.net import middleware
from fogiac.plan.model import (
    ROS_EPHEMERAL,
    ROS_MASTER_PORT,
    SSH_PORT,
    CostLine,
    HostSpec,
    MachineImage,
    Rule,
    SecurityGroup,
)
from fogiac.plan.placement import Placement, Tags, autostop_for, host_per_node, replica_groups, ssh_sources
from fogiac.targets.aws.catalog import catalog, on_demand, spot_price
from fogiac.targets.aws.manifest import CLOUD as AWS
from fogiac.targets.aws.manifest import network_of
from fogiac.targets.aws.model import ImageQuery, Subnet, VpcSpec, VpnSpec, zone_subnet

_WORLD = "0.0.0.0/0"
AUTOSTOP_MINUTES = 30  # unless the manifest says otherwise, an EC2 host idle this long powers itself off

# Ubuntu LTS from Canonical for CPU types; AWS's Deep Learning Base image (NVIDIA driver and
# container toolkit preinstalled) for GPU types; each for the machine's architecture (Graviton is
# arm64). ROS itself runs in containers on the hosts.
UBUNTU = ImageQuery(
    owners=("099720109477",),
    name_pattern="ubuntu/images/hvm-ssd-gp3/ubuntu-noble-24.04-amd64-server-*",
    description="Ubuntu 24.04 LTS (Canonical)",
)
NVIDIA = ImageQuery(
    owners=("amazon",),
    name_pattern="Deep Learning Base OSS Nvidia Driver GPU AMI (Ubuntu 22.04) *",
    description="AWS Deep Learning Base, NVIDIA driver, Ubuntu 22.04",
)
UBUNTU_ARM64 = ImageQuery(
    owners=("099720109477",),
    name_pattern="ubuntu/images/hvm-ssd-gp3/ubuntu-noble-24.04-arm64-server-*",
    description="Ubuntu 24.04 LTS (Canonical), arm64",
)
NVIDIA_ARM64 = ImageQuery(
    owners=("amazon",),
    name_pattern="Deep Learning ARM64 Base OSS Nvidia Driver GPU AMI (Ubuntu 22.04) *",
    description="AWS Deep Learning ARM64 Base, NVIDIA driver, Ubuntu 22.04",
)
IMAGES = {("x86_64", False): UBUNTU, ("x86_64", True): NVIDIA, ("arm64", False): UBUNTU_ARM64,
          ("arm64", True): NVIDIA_ARM64}


def image_for(spec: MachineSpec) -> MachineImage:
    """The image the machine's architecture and GPU call for."""
    return IMAGES[(spec.arch if spec.arch == "arm64" else "x86_64", spec.has_gpu)]


def _network(manifest: Manifest, zones: tuple[str, ...] = ()) -> VpcSpec:
    """The hosts' and the VPN's subnets in the plan's zone, and one hosts subnet per zone a replica uses."""
    vpc = network_of(manifest.network).vpc_cidr
    prefix = max(vpc.prefixlen + 1, 24) if vpc.prefixlen < 24 else vpc.prefixlen + 1
    blocks = list(vpc.subnets(new_prefix=prefix))
    if len(blocks) < 2 + len(zones):
        raise PlanError(f"network.vpc_cidr: {vpc} has room for {len(blocks)} subnets; the replicas' {len(zones)} "
                        f"zones need {2 + len(zones)} (a larger range, e.g. a /16)")
    first, second = blocks[:2]
    return VpcSpec(
        vpc_cidr=str(vpc),
        subnets=(
            Subnet(name="hosts", cidr=str(first), role="instances", public=True),
            Subnet(name="vpn", cidr=str(second), role="vpn", public=False),
        ) + tuple(Subnet(name=zone_subnet(zone), cidr=str(block), role="instances", public=True, zone=zone)
                  for zone, block in zip(zones, blocks[2:], strict=False)),
        flow_logs=network_of(manifest.network).flow_logs,
    )


def replica_zones(manifest: Manifest, hosts: tuple[HostSpec, ...],
                  groups: Mapping[str, tuple[str, ...]]) -> tuple[tuple[HostSpec, ...], tuple[str, ...]]:
    """Each replica's host in a zone of its own where the region has enough zones offering its machine:
    the plan's zone first, then the others in order; a zone that does not offer the type is skipped and
    said. Returns the hosts (replicas' with ``zone`` set) and the plan's notes."""
    region = manifest.cloud.region
    first = manifest.cloud.zone or f"{region}a"
    cat = AWS.catalogue
    notes: list[str] = []
    zoned: dict[str, str] = {}
    by_name = {h.name: h for h in hosts}
    for node, names in groups.items():
        machine = by_name[names[0]].machine
        known = cat.region_zones(region)
        ordered = [first] + sorted(z for z in known if z != first)
        offering = cat.zones_offering(machine, region)
        if offering is None:  # the catalogue (an older or refreshed one) lists no zones here
            usable = [first] + [f"{region}{letter}" for letter in "abcdef" if f"{region}{letter}" != first]
            usable = usable[:len(names)]
            notes.append(f"{node}: the catalogue lists no zones of {region}; replicas assumed in "
                         f"{', '.join(usable)} (`fogiac up` checks them)")
        else:
            usable = [z for z in ordered if z in offering]
            notes += [f"{node}: zone {z} does not offer {machine}, skipped" for z in ordered if z not in offering]
        if not usable:
            raise PlanError(f"nodes.{node}: no zone of {region} offers {machine}")
        for index, name in enumerate(names):
            zoned[name] = usable[index % len(usable)]
        spread = ", ".join(f"{name} in {zoned[name]}" for name in names)
        shared = " (fewer zones offer it than replicas: some share a zone)" if len(usable) < len(names) else ""
        notes.append(f"{node}: {len(names)} replicas, {spread}{shared}")
        host = by_name[names[0]]
        each = f"${host.usd_per_hour:.4f}/h each" if host.usd_per_hour else "cost unknown"
        notes.append(f"{node}: {len(names)} machines priced ({machine}, {each}); the cost guard counts every one")
        if host.spot:
            notes.append(f"{node}: spot is safe with replicas: a reclaimed replica's requests are answered by "
                         "the others while `fogiac up` replaces it")
    placed = tuple(dataclasses.replace(h, zone=zoned[h.name]) if h.name in zoned else h for h in hosts)
    return placed, tuple(notes)


AWS_RESERVED_PER_SUBNET = 5  # the network, the router, DNS, one for the future, the broadcast


def _room_for(manifest: Manifest, network: VpcSpec, machines: int) -> None:
    """The hosts subnet holds an address for every machine: found at validate, not when EC2 runs out at up."""
    subnet = next(s for s in network.subnets if s.role == "instances")
    usable = ipaddress.IPv4Network(subnet.cidr).num_addresses - AWS_RESERVED_PER_SUBNET
    if machines > usable:
        wider = ("give vpc_cidr a shorter prefix (a /24 or wider)" if ipaddress.IPv4Network(subnet.cidr).prefixlen > 24
                 else "fogiac's hosts subnet is a /24 at most: split the nodes into several stacks")
        raise FogiacError(
            f"network.vpc_cidr: {network.vpc_cidr} gives the hosts subnet {subnet.cidr}, {usable} usable "
            f"addresses (AWS keeps 5), for {machines} machines; {wider}")


def _egress(manifest: Manifest, inside: list[str]) -> tuple[Rule, ...]:
    """Anything inside the VPC (and to VPN clients), and only the manifest's TCP ports (80 and 443 by
    default: packages, images, APIs) beyond it. DNS (the VPC's resolver) and time (Amazon Time Sync,
    169.254.169.123) need no rule: security groups do not filter them."""
    rules = [Rule("-1", 0, 0, cidr, "inside the VPC" if i == 0 else "to VPN clients") for i, cidr in enumerate(inside)]
    rules += [Rule("tcp", port, port, _WORLD, f"TCP {port} to the internet (updates, images and packages)")
              for port in manifest.network.egress_tcp]
    return tuple(rules)


def _firewall(manifest: Manifest, ssh_from: tuple[str, ...], *, vpn_mode: bool,
              host_cidrs: tuple[str, ...] = ()) -> tuple[SecurityGroup, ...]:
    """Least privilege: SSH from ssh_from only; the middleware's port (and, for ROS 1, the master's and
    the nodes') from the VPC and VPN clients (a fleet's VPN clients: the middleware's port only); in proxy
    mode the middleware's port also from ssh_from, never from the world. ROS 2 traffic leaves a host only
    through its Zenoh router."""
    carrier = middleware.for_distro(manifest.ros.distro)
    port, what = carrier.port, carrier.rule_description
    ranges = network_of(manifest.network)
    inside = [str(ranges.vpc_cidr)]
    if vpn_mode:
        inside.append(str(ranges.client_cidr))
    ingress = [Rule("tcp", SSH_PORT, SSH_PORT, cidr, "SSH from the operator") for cidr in ssh_from]
    # ROS 1 over the VPN reaches the master and its nodes; ROS 2 crosses only the router. Not a fleet's robots
    # (vpn mode): the master is every robot's, so a robot there would bypass the relay's per-robot access. The
    # endpoint source-NATs its clients into the VPC, so the master's and nodes' ports are then opened to the
    # hosts' subnets only (not the VPN's, nor the client range): the robots reach the relay's port alone.
    fleet_vpn = vpn_mode and bool(manifest.robots)
    ros_from = list(host_cidrs) if fleet_vpn else inside
    for cidr in dict.fromkeys([*ros_from, *inside]):
        if carrier.node_master and cidr in ros_from:
            ingress += [
                Rule("tcp", ROS_MASTER_PORT, ROS_MASTER_PORT, cidr, "ROS master"),
                Rule("tcp", ROS_EPHEMERAL[0], ROS_EPHEMERAL[1], cidr, "ROS node ports (TCPROS, XML-RPC)"),
            ]
        if cidr in inside:
            ingress.append(Rule("tcp", port, port, cidr, what))
    if not vpn_mode:
        ingress += [Rule("tcp", port, port, cidr, f"{what} from the edge") for cidr in ssh_from]
    hosts = SecurityGroup(
        name="hosts",
        description=f"fogiac hosts: SSH from the operator, ROS and {carrier.name} from inside only",
        ingress=tuple(ingress),
        egress=_egress(manifest, inside),
    )
    groups = [hosts]
    if vpn_mode:
        groups.append(
            SecurityGroup(
                name="vpn",
                description="fogiac Client VPN endpoint: no ingress, egress to the VPC only",
                ingress=(),
                egress=(Rule("-1", 0, 0, str(ranges.vpc_cidr), "VPN clients to the VPC"),),
            )
        )
    return tuple(groups)


def _vpn(manifest: Manifest, stack: str, network: VpcSpec) -> VpnSpec:
    return VpnSpec(
        client_cidr=str(network_of(manifest.network).client_cidr),
        server_name=server_name(stack),
        target_subnet="vpn",
        authorize_cidr=network.vpc_cidr,
    )


def cost_lines(hosts: tuple[HostSpec, ...], vpn: VpnSpec | None, robots: int = 1) -> tuple[CostLine, ...]:
    """Each instance at its on-demand price, a spot one with its spot estimate beside; the Client VPN: one subnet
    association, and one connection per robot (``robots``: a fleet's count), because AWS bills each connected
    client by the hour and every robot's edge joins the VPC through a Client VPN connection of its own."""
    lines = [
        CostLine(f"instance {h.name} ({h.machine}{', spot' if h.spot else ''}{', ' + h.zone if h.zone else ''})", 1,
                 h.usd_per_hour,
                 spot_usd_per_hour=h.spot_usd_per_hour if h.spot else None)
        for h in hosts
    ]
    if vpn is not None:
        cat = catalog()
        lines.append(CostLine("Client VPN subnet association", 1, cat.vpn_association_usd_per_hour))
        lines.append(CostLine("Client VPN connection (the edge)", 1, cat.vpn_connection_usd_per_hour) if robots <= 1
                     else CostLine(f"Client VPN connections ({robots} robots, one each)", robots,
                                   cat.vpn_connection_usd_per_hour, per_robot=True))
    return tuple(lines)


def place(manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
    """One EC2 instance per node, in a VPC of its own; the Client VPN in vpn mode."""
    region = manifest.cloud.region
    vpn_mode = manifest.network.mode == "vpn"
    hosts, node_hosts = host_per_node(
        manifest, stack=stack, tags=tags, usd_per_hour=lambda spec: on_demand(spec.name, region), spot=True,
        spot_usd_per_hour=lambda spec: spot_price(spec.name, region), image=image_for)
    _room_for(manifest, _network(manifest), len(hosts))  # a machine a node (and a replica): before any zone is chosen
    groups = replica_groups(manifest)
    hosts, notes = replica_zones(manifest, hosts, groups)
    network = _network(manifest, tuple(sorted({h.zone for h in hosts if h.zone is not None})))
    vpn = _vpn(manifest, stack, network) if vpn_mode else None
    return Placement(
        hosts=hosts, node_hosts=node_hosts, mode=manifest.network.mode,
        connect_via="private" if vpn_mode else "public", network=network,
        security_groups=_firewall(manifest, ssh_sources(manifest), vpn_mode=vpn_mode,
                                  host_cidrs=tuple(s.cidr for s in network.subnets if s.role == "instances")),
        vpn=vpn,
        cost=cost_lines(hosts, vpn, robots=len(manifest.robots) or 1),
        autostop=autostop_for(manifest, power="machine", default_minutes=AUTOSTOP_MINUTES),
        replica_hosts=groups, notes=notes,
    )
