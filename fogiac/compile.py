"""Manifest -> Plan: a pure, deterministic function. No network, no engine, no files.

Everything later stages decide from the manifest is decided here once: the stack's name and
tags, the subnet layout, every security rule, each host's hardware, image and provisioning
steps, the VPN settings, the relay routes and the hourly cost.
"""

from __future__ import annotations

import ipaddress

from fogiac.catalog import catalog
from fogiac.errors import PlanError
from fogiac.manifest import Manifest, Node
from fogiac.plan import (
    OPERATOR,
    RELAY_PORT,
    ROS_EPHEMERAL,
    ROS_MASTER_PORT,
    SSH_PORT,
    CostLine,
    HostSpec,
    ImageQuery,
    LaunchSpec,
    NetworkSpec,
    NodeSpec,
    Plan,
    RelayRoute,
    Rule,
    SecurityGroup,
    Subnet,
    VpnSpec,
    server_name,
)

TARGETS = ("aws", "hosts", "local")
_WORLD = "0.0.0.0/0"

# Ubuntu LTS from Canonical for CPU types; AWS's Deep Learning Base image (NVIDIA driver and
# container toolkit preinstalled) for GPU types. ROS itself runs in containers on the hosts.
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


def stack_name(manifest: Manifest, environment: str = "dev") -> str:
    return f"{manifest.name}-{environment}"


def compile_plan(manifest: Manifest, *, target: str | None = None, environment: str = "dev") -> Plan:
    """Compile ``manifest`` for ``target`` (default: the manifest's own provider)."""
    target = target or manifest.cloud.provider
    if target not in TARGETS:
        raise PlanError(f"unknown target {target!r}; valid: {', '.join(TARGETS)}")
    stack = stack_name(manifest, environment)
    tags = (("fogiac:stack", stack), ("fogiac:manifest", manifest.name)) + tuple(sorted(manifest.tags.items()))
    on_aws = target == "aws"
    vpn_mode = on_aws and manifest.network.mode == "vpn"
    ssh_from = (
        (OPERATOR,) if manifest.network.ssh_from == "auto" else tuple(str(c) for c in manifest.network.ssh_from)
    )
    network = _network(manifest) if on_aws else None
    hosts, placement = _hosts(manifest, target, stack, tags)
    nodes = tuple(_node(node, placement[node.name]) for node in manifest.nodes)
    plan = Plan(
        stack=stack,
        manifest_name=manifest.name,
        environment=environment,
        target=target,
        region=manifest.cloud.region,
        zone=manifest.cloud.zone or f"{manifest.cloud.region}a",
        zone_chosen=manifest.cloud.zone is not None,
        ros_distro=manifest.ros.distro,
        mode=manifest.network.mode if on_aws else "relay",
        edge_master=manifest.edge.ros_master,
        ssh_from=ssh_from,
        network=network,
        security_groups=_firewall(manifest, ssh_from, vpn_mode=vpn_mode) if on_aws else (),
        vpn=_vpn(manifest, stack, network) if vpn_mode and network else None,
        hosts=hosts,
        nodes=nodes,
        relay=tuple(_route(manifest, host, nodes, target) for host in hosts),
        tags=tags,
    )
    return _with_cost(plan)


def _network(manifest: Manifest) -> NetworkSpec:
    vpc = manifest.network.vpc_cidr
    prefix = max(vpc.prefixlen + 1, 24) if vpc.prefixlen < 24 else vpc.prefixlen + 1
    first, second = list(vpc.subnets(new_prefix=prefix))[:2]
    return NetworkSpec(
        vpc_cidr=str(vpc),
        subnets=(
            Subnet(name="hosts", cidr=str(first), role="instances", public=True),
            Subnet(name="vpn", cidr=str(second), role="vpn", public=False),
        ),
    )


def _firewall(manifest: Manifest, ssh_from: tuple[str, ...], *, vpn_mode: bool) -> tuple[SecurityGroup, ...]:
    """Least privilege: SSH from ssh_from only; ROS and relay ports from the VPC (and VPN clients)."""
    inside = [str(manifest.network.vpc_cidr)]
    if vpn_mode:
        inside.append(str(manifest.network.client_cidr))
    ingress = [Rule("tcp", SSH_PORT, SSH_PORT, cidr, "SSH from the operator") for cidr in ssh_from]
    for cidr in inside:
        ingress += [
            Rule("tcp", ROS_MASTER_PORT, ROS_MASTER_PORT, cidr, "ROS master"),
            Rule("tcp", ROS_EPHEMERAL[0], ROS_EPHEMERAL[1], cidr, "ROS node ports (TCPROS, XML-RPC)"),
            Rule("tcp", RELAY_PORT, RELAY_PORT, cidr, "fogiac relay (mutual TLS)"),
        ]
    if not vpn_mode:
        ingress += [Rule("tcp", RELAY_PORT, RELAY_PORT, cidr, "fogiac relay from the edge") for cidr in ssh_from]
    hosts = SecurityGroup(
        name="hosts",
        description="fogiac hosts: SSH from the operator, ROS and relay from inside only",
        ingress=tuple(ingress),
        egress=(Rule("-1", 0, 0, _WORLD, "updates, images and packages"),),
    )
    groups = [hosts]
    if vpn_mode:
        groups.append(
            SecurityGroup(
                name="vpn",
                description="fogiac Client VPN endpoint: no ingress, egress to the VPC only",
                ingress=(),
                egress=(Rule("-1", 0, 0, str(manifest.network.vpc_cidr), "VPN clients to the VPC"),),
            )
        )
    return tuple(groups)


def _vpn(manifest: Manifest, stack: str, network: NetworkSpec) -> VpnSpec:
    return VpnSpec(
        client_cidr=str(manifest.network.client_cidr),
        server_name=server_name(stack),
        target_subnet="vpn",
        authorize_cidr=network.vpc_cidr,
    )


def _steps(target: str, nodes: list[Node]) -> tuple[str, ...]:
    steps = ["connect", "runtime"]
    if any(n.launch is not None for n in nodes):
        steps += ["workspace", "env_script"]
    steps += ["services", "relay", "health"]
    return tuple(steps)


def _hosts(
    manifest: Manifest, target: str, stack: str, tags: tuple[tuple[str, str], ...]
) -> tuple[tuple[HostSpec, ...], dict[str, str]]:
    types = catalog().types
    if target != "hosts":
        hosts = []
        for node in manifest.nodes:
            spec = types[node.machine]
            hosts.append(
                HostSpec(
                    name=node.name,
                    machine=node.machine,
                    vcpus=spec.vcpus,
                    gpus=spec.gpus,
                    memory_gib=spec.memory_gib,
                    usd_per_hour=spec.usd_per_hour[manifest.cloud.region] if target == "aws" else 0.0,
                    spot=node.spot and target == "aws",
                    disk_gb=node.disk_gb,
                    nodes=(node.name,),
                    steps=_steps(target, [node]),
                    tags=tags + (("fogiac:node", node.name), ("Name", f"{stack}-{node.name}")),
                    image=(NVIDIA if spec.has_gpu else UBUNTU) if target == "aws" else None,
                    address="127.0.0.1" if target == "local" else None,
                )
            )
        return tuple(hosts), {n.name: n.name for n in manifest.nodes}
    machines = manifest.cloud.hosts
    if not machines:
        raise PlanError("cloud.hosts: the hosts target needs at least one machine")
    placement = {
        node.name: node.host or machines[i % len(machines)].name for i, node in enumerate(manifest.nodes)
    }
    hosts = []
    for machine in machines:
        placed = [n for n in manifest.nodes if placement[n.name] == machine.name]
        if not placed:
            continue
        for node in placed:
            if node.gpu and machine.gpus == 0:
                raise PlanError(f"nodes.{node.name}: needs a GPU but host {machine.name!r} has gpus: 0")
        hosts.append(
            HostSpec(
                name=machine.name,
                machine="lab",
                vcpus=0,
                gpus=machine.gpus,
                memory_gib=0.0,
                usd_per_hour=0.0,
                spot=False,
                disk_gb=0,
                nodes=tuple(n.name for n in placed),
                steps=_steps("hosts", placed),
                tags=tags + (("fogiac:node", ",".join(n.name for n in placed)),),
                address=machine.address,
                user=machine.user,
                port=machine.port,
                key=str(machine.key),
            )
        )
    return tuple(hosts), placement


def _node(node: Node, host: str) -> NodeSpec:
    lists = node.topics if node.topics != "auto" else None
    return NodeSpec(
        name=node.name,
        host=host,
        kind=node.kind,
        image=node.image,
        command=node.command,
        launch=(
            LaunchSpec(
                package=node.launch.package,
                file=node.launch.file,
                workspace=str(node.launch.workspace),
                env_script=str(node.launch.env_script) if node.launch.env_script else None,
            )
            if node.launch
            else None
        ),
        workload=node.workload,
        gpu=node.gpu,
        env=tuple(sorted(node.env.items())),
        topics_auto=lists is None,
        topics_in=lists.inputs if lists else (),
        topics_out=lists.outputs if lists else (),
    )


def _route(manifest: Manifest, host: HostSpec, nodes: tuple[NodeSpec, ...], target: str) -> RelayRoute:
    mine = [n for n in nodes if n.host == host.name]
    relay = manifest.relay
    listed = relay.topics if relay.topics != "auto" else ()
    to_cloud = tuple(sorted({t for n in mine for t in n.topics_in}))
    to_edge = tuple(sorted({t for n in mine for t in n.topics_out}))
    compression = (
        (("*", relay.compression),) if isinstance(relay.compression, str) else tuple(sorted(relay.compression.items()))
    )
    via = {"aws": "private" if manifest.network.mode == "vpn" else "public", "hosts": "address", "local": "loopback"}
    return RelayRoute(
        host=host.name,
        connect_via=via[target],
        port=RELAY_PORT,
        auto=relay.topics == "auto" and any(n.topics_auto for n in mine),
        to_cloud=to_cloud,
        to_edge=to_edge,
        listed=tuple(sorted(listed)),
        compression=compression,
        queue_size=relay.queue_size,
    )


def _with_cost(plan: Plan) -> Plan:
    if plan.target != "aws":
        return plan
    lines = [
        CostLine(f"instance {h.name} ({h.machine}{', spot: at most' if h.spot else ''})", 1, h.usd_per_hour)
        for h in plan.hosts
    ]
    if plan.vpn is not None:
        cat = catalog()
        lines.append(CostLine("Client VPN subnet association", 1, cat.vpn_association_usd_per_hour))
        lines.append(CostLine("Client VPN connection (the edge)", 1, cat.vpn_connection_usd_per_hour))
    return Plan(**{**plan.__dict__, "cost": tuple(lines)})


def check_no_world_ingress(plan: Plan) -> None:
    """The invariant every plan keeps: no ingress from 0.0.0.0/0 or ::/0."""
    for group in plan.security_groups:
        for rule in group.ingress:
            if rule.cidr != OPERATOR and ipaddress.ip_network(rule.cidr).prefixlen == 0:
                raise PlanError(f"security group {group.name!r} would accept {rule.cidr} on port {rule.from_port}")
