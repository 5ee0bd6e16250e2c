"""Manifest -> Plan: a pure, deterministic function. No network, no engine, no files.

Everything later stages decide from the manifest is decided here once: the stack's name and
tags, the nodes, the middleware (from the ROS distribution), the routes and the hourly cost.
Where the hosts are, what network they sit in and what they cost is the target's part
(:class:`fogiac.plan.placement.Placement`), asked of the target registry, so a new target never
edits this module.
"""

from __future__ import annotations

import re

from fogiac import targets
from fogiac.errors import FogiacError
from fogiac.manifest.replicas import warn_unchecked
from fogiac.manifest.schema import Manifest, Node
from fogiac.net import middleware
from fogiac.plan.model import (
    BuildSpec,
    ConnectVia,
    EdgeSpec,
    HostSpec,
    LaunchSpec,
    NodeSpec,
    Plan,
    RelayRoute,
    Replica,
)
from fogiac.plan.placement import Placement, ssh_sources

_ENVIRONMENT = re.compile(r"^[a-z]([a-z0-9-]{0,38}[a-z0-9])?$")


def stack_name(manifest: Manifest, environment: str = "dev") -> str:
    """``<name>-<environment>``, or ``<name>--<environment>`` when the environment holds a '-': a folder
    name, a tag and a word in rendered units and scripts, so the environment obeys the same DNS-safe
    rule as the manifest's name. Neither holds '--', so no two (name, environment) pairs share a stack
    (``robot-prod`` + ``dev`` and ``robot`` + ``prod-dev`` were both ``robot-prod-dev``); an environment
    without a '-' (``dev``, ``prod``) keeps the name it always had."""
    if not _ENVIRONMENT.match(environment):
        raise FogiacError(f"--env {environment!r} is not DNS-safe (lowercase letters, digits, '-', up to 40)")
    if "--" in environment:
        raise FogiacError(f"--env {environment!r} holds '--', which fogiac keeps for joining the name and the "
                          "environment")
    return f"{manifest.name}{'--' if '-' in environment else '-'}{environment}"


def stack_names(manifest: Manifest, environment: str) -> tuple[str, str | None]:
    """The stack's name (:func:`stack_name`) and the one fogiac gave it before ``--``
    (``<name>-<environment>``) where it differs, else None: the record decides which a deployment has
    (:func:`fogiac.deployment.stack_for`)."""
    new = stack_name(manifest, environment)
    old = f"{manifest.name}-{environment}"
    return new, (old if old != new else None)


def compile_plan(manifest: Manifest, *, target: str | None = None, environment: str = "dev",
                 stack: str | None = None) -> Plan:
    """Compile ``manifest`` for ``target`` (default: the manifest's own provider); ``stack``: the name a
    deployment made under an older naming still has (:func:`stack_names`), else :func:`stack_name`."""
    name = target or manifest.cloud.provider
    place = targets.placer(name)  # loads only what the target decides at compile time
    carrier = middleware.for_distro(manifest.ros.distro)
    stack = stack or stack_name(manifest, environment)
    tags = (("fogiac:stack", stack), ("fogiac:manifest", manifest.name)) + tuple(sorted(manifest.tags.items()))
    placed = place(manifest, stack=stack, tags=tags)  # its security groups checked themselves when made
    nodes = tuple(_node(node, placed.node_hosts[node.name], fleet=bool(manifest.robots)) for node in manifest.nodes)
    return Plan(
        stack=stack,
        manifest_name=manifest.name,
        environment=environment,
        target=name,
        region=manifest.cloud.region,
        zone=manifest.cloud.zone or f"{manifest.cloud.region}a",
        zone_chosen=manifest.cloud.zone is not None,
        ros_distro=manifest.ros.distro,
        middleware=carrier.name,
        mode=placed.mode,
        # the manifest's edge: block, the one-robot shorthand: a list of one edge, named after the stack
        edges=_edges(manifest, stack, carrier),
        ssh_from=ssh_sources(manifest),
        network=placed.network,
        security_groups=placed.security_groups,
        vpn=placed.vpn,
        hosts=placed.hosts,
        nodes=nodes,
        routes=tuple(_route(manifest, host, nodes, placed.connect_via, carrier.port, _replicas(manifest, placed))
                     for host in placed.hosts),
        tags=tags,
        cost=placed.cost,
        autostop=placed.autostop,
        middleware_settings=_settings(manifest, carrier.name),
        notes=placed.notes + _unchecked(manifest),
        registries=tuple((r.server, r.username, r.password.secret) for r in manifest.cloud.registries),
        budget_usd_per_hour=manifest.cloud.budget_usd_per_hour,
    )


def _edges(manifest: Manifest, stack: str, carrier: middleware.Middleware) -> tuple[EdgeSpec, ...]:
    """The fleet's robots, each its own edge; else the ``edge:`` block, the one-robot shorthand: a list of one
    edge, named after the stack, whose certificate and files keep the names of before fleets."""
    if not manifest.robots:
        return (EdgeSpec(name=stack, entry=carrier.edge_entry(manifest.edge), shorthand=True),)
    return tuple(EdgeSpec(name=robot.name, entry=carrier.edge_entry(robot), compression=robot.compression)
                 for robot in manifest.robots)


def _unchecked(manifest: Manifest) -> tuple[str, ...]:
    """Replicated nodes' out topics without a stated type: said in the plan, and warned in one line."""
    lines = tuple(line for node in manifest.nodes if (line := node.unchecked_match()) is not None)
    for line in lines:
        warn_unchecked(line)
    return lines


def _replicas(manifest: Manifest, placed: Placement) -> dict[str, Replica]:
    """host -> the replica it carries, for every replicated node's hosts."""
    found: dict[str, Replica] = {}
    for node in manifest.nodes:
        hosts = placed.replica_hosts.get(node.name, ())
        if node.replicas > 1 and len(hosts) != node.replicas:
            raise FogiacError(f"nodes.{node.name}: the target placed {len(hosts)} of its {node.replicas} replicas")
        hedge = node.hedge
        for index, host in enumerate(hosts):
            found[host] = Replica(group=node.name, index=index, count=node.replicas, match=node.reply_match,
                                  hedge="all" if hedge == "all" else "delayed",
                                  hedge_delay_s=0.0 if hedge == "all" else hedge.delay_ms / 1000,
                                  types=tuple(sorted(node.message_types.items())))
    return found


def _settings(manifest: Manifest, carrier: str) -> tuple[tuple[str, object], ...]:
    """The middleware's own manifest block (validated by its model), as sorted JSON-ready pairs."""
    block = manifest.block(carrier)
    return tuple(sorted(block.model_dump(mode="json").items())) if block is not None else ()


def _node(node: Node, host: str, *, fleet: bool = False) -> NodeSpec:
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
                requirements=str(node.launch.requirements) if node.launch.requirements else None,
            )
            if node.launch
            else None
        ),
        workload=node.workload,
        build=BuildSpec(context=str(node.build.context), dockerfile=node.build.dockerfile) if node.build else None,
        gpu=node.needs_gpu,
        env=tuple(sorted((k, v) for k, v in node.env.items() if isinstance(v, str))),
        secrets=tuple(sorted((k, v.secret) for k, v in node.env.items() if not isinstance(v, str))),
        topics_auto=lists is None,
        topics_in=lists.inputs if lists else (),
        topics_out=lists.outputs if lists else (),
        serves=node.serve if isinstance(node.serve, tuple) else (),
        per_robot=node.serve == "per_robot",
        reply_match=node.reply_match if fleet else None,  # a fleet's shared node: whose request a reply answers
    )


def _route(manifest: Manifest, host: HostSpec, nodes: tuple[NodeSpec, ...], via: ConnectVia,
           port: int, replicas: dict[str, Replica]) -> RelayRoute:
    mine = [n for n in nodes if n.name in host.nodes]
    relay = manifest.relay
    listed = relay.topics if relay.topics != "auto" else ()
    to_cloud = tuple(sorted({t for n in mine for t in n.topics_in}))
    to_edge = tuple(sorted({t for n in mine for t in n.topics_out}))
    compression = (
        (("*", relay.compression),) if isinstance(relay.compression, str) else tuple(sorted(relay.compression.items()))
    )
    return RelayRoute(
        host=host.name,
        connect_via=via,
        port=host.relay_port or port,
        auto=relay.topics == "auto" and any(n.topics_auto for n in mine),
        to_cloud=to_cloud,
        to_edge=to_edge,
        listed=tuple(sorted(listed)),
        compression=compression,
        queue_size=relay.queue_size,
        replica=replicas.get(host.name),
    )
