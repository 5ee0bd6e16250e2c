"""What a target decides when a manifest is compiled for it: hosts, node placement, network.

:func:`fogiac.plan.compile.compile_plan` asks the target named by ``--target`` (or the
manifest) for a :class:`Placement` and builds the rest of the Plan around it. The helpers here
are shared by targets that give each node a machine of its own (``aws``, ``local``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

from fogiac.errors import PlanError
from fogiac.manifest.clouds import variant
from fogiac.manifest.machines import MachineSpec
from fogiac.manifest.schema import Manifest, Node
from fogiac.plan.model import (
    OPERATOR,
    AutostopPower,
    AutostopSpec,
    ConnectVia,
    CostLine,
    EdgeVpn,
    HostSpec,
    MachineImage,
    NetworkMode,
    NetworkSpec,
    SecurityGroup,
)

Tags = tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class Placement:
    """A target's part of the Plan."""

    hosts: tuple[HostSpec, ...]
    node_hosts: Mapping[str, str]  # node name -> host name
    mode: NetworkMode
    connect_via: ConnectVia  # which address of a host the edge relay dials
    network: NetworkSpec | None = None
    security_groups: tuple[SecurityGroup, ...] = ()
    vpn: EdgeVpn | None = None
    cost: tuple[CostLine, ...] = ()
    autostop: AutostopSpec | None = None
    # node name -> the hosts of its replicas in index order, for a node with replicas: N > 1
    replica_hosts: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    notes: tuple[str, ...] = ()  # what the plan says about where the replicas went (and did not)


def replica_name(node: str, index: int, count: int) -> str:
    """The host of replica ``index`` (0-based) of ``node``: the node's own name when it runs once, else
    ``<node>-r1`` ... ``<node>-rN`` (stable: the same replica keeps its host, and its machine, across plans)."""
    return node if count == 1 else f"{node}-r{index + 1}"


def replica_groups(manifest: Manifest) -> dict[str, tuple[str, ...]]:
    """node -> its replicas' hosts, for the nodes placed one host per replica (aws, local)."""
    return {n.name: tuple(replica_name(n.name, i, n.replicas) for i in range(n.replicas))
            for n in manifest.nodes if n.replicas > 1}


def autostop_for(manifest: Manifest, *, power: AutostopPower, default_minutes: float | None) -> AutostopSpec | None:
    """``cloud.autostop`` for a target: unset means the target's default (None: off)."""
    asked = manifest.cloud.autostop
    if asked == "off" or (asked is None and default_minutes is None):
        return None
    if asked is None:
        return AutostopSpec(idle_s=float(default_minutes or 0) * 60, action="stop", power=power)
    return AutostopSpec(idle_s=asked.idle_minutes * 60, action=asked.action, power=power)


def ssh_sources(manifest: Manifest) -> tuple[str, ...]:
    """``network.ssh_from`` as CIDR strings; OPERATOR stands for ``auto`` until preflight resolves it."""
    if manifest.network.ssh_from == "auto":
        return (OPERATOR,)
    return tuple(str(c) for c in manifest.network.ssh_from)


def steps_for(nodes: Sequence[Node]) -> tuple[str, ...]:
    """The provisioning steps a host runs for ``nodes``, in order."""
    steps = ["connect", "runtime"]
    if any(n.workload or n.build or (n.launch and n.launch.requirements) for n in nodes):
        steps.append("images")  # a launch package's requirements make an image on a container host
    steps.append("venv")  # fogiac's own requirements for the relay, and native workload nodes'
    if any(n.launch is not None for n in nodes):
        steps += ["workspace", "env_script"]
    steps += ["services", "link", "health"]
    return tuple(steps)


def host_per_node(manifest: Manifest, *, stack: str, tags: Tags,
                  usd_per_hour: Callable[[MachineSpec], float | None] = lambda spec: 0.0,
                  spot: bool = False,
                  spot_usd_per_hour: Callable[[MachineSpec], float | None] = lambda spec: None,
                  image: Callable[[MachineSpec], MachineImage | None] = lambda spec: None,
                  address: str | None = None,
                  runtime: Literal["auto", "container", "native"] = "auto",
                  ) -> tuple[tuple[HostSpec, ...], dict[str, str]]:
    """One host per node, of the node's machine type (one per replica of a replicated node, each of the
    same type): how ``aws`` and ``local`` place nodes."""
    sizes = variant(manifest.cloud.provider)
    hosts = []
    names = {n.name for n in manifest.nodes}
    for node in manifest.nodes:
        choice = node.machine_choice(manifest.cloud.region, spot=node.spot and spot, provider=manifest.cloud.provider)
        spec = sizes.machine(choice.machine)
        assert spec is not None, choice.machine  # the variant chose it
        for index in range(node.replicas):
            name = replica_name(node.name, index, node.replicas)
            if node.replicas > 1 and name in names:
                raise PlanError(f"nodes.{node.name}: its replica host {name!r} has the name of another node; "
                                "rename one of them")
            # a replica's host is not named after its node: the target finds it by fogiac:host
            replica = ((("fogiac:host", name), ("fogiac:replica", f"{index + 1}/{node.replicas}"))
                       if node.replicas > 1 else ())
            hosts.append(HostSpec(
                name=name, machine=choice.machine, alternatives=choice.alternatives,
                chosen_for=choice.chosen_for, ranked_by=choice.ranked_by,
                vcpus=spec.vcpus, gpus=spec.gpus, memory_gib=spec.memory_gib,
                usd_per_hour=usd_per_hour(spec), spot=node.spot and spot,
                spot_usd_per_hour=spot_usd_per_hour(spec) if node.spot and spot else None,
                disk_gb=node.disk_gb, nodes=(node.name,),
                steps=steps_for([node]), tags=tags + (("fogiac:node", node.name), ("Name", f"{stack}-{name}"))
                + replica,
                image=image(spec), address=address, runtime=runtime,
            ))
    return tuple(hosts), {n.name: replica_name(n.name, 0, n.replicas) for n in manifest.nodes}
