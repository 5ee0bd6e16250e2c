"""Where the ``hosts`` target puts a manifest's nodes: on the machines the manifest names, each
stack on ports of its own (:func:`stack_ports`); a replicated node's replicas each on a machine of its
own (``replica_hosts``, else the spare machines in order)."""

from __future__ import annotations

import hashlib

from fogiac.errors import PlanError
from fogiac.manifest.schema import Manifest
from fogiac.plan.model import HostSpec
from fogiac.plan.placement import Placement, Tags, autostop_for, steps_for

# Stacks' port pairs (master, master + 1 for the relay) lie in 20000-29999: below Linux's ephemeral
# range (32768-60999), where nodes listen, and clear of ROS's 11311 and the relay's 11411.
_PORTS_FROM, _PORT_PAIRS = 20000, 5000


def stack_ports(stack: str) -> tuple[int, int]:
    """(ROS master port, relay port) of ``stack`` on every host: the same on every run, from its name.

    Two stacks meet on one pair once in 5000; the second master then cannot bind and its health
    step names the port, rather than two stacks silently sharing a graph.
    """
    pair = int.from_bytes(hashlib.sha256(stack.encode()).digest()[:4], "big") % _PORT_PAIRS
    master = _PORTS_FROM + 2 * pair
    return master, master + 1


def place(manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
    machines = manifest.cloud.hosts
    if not machines:
        raise PlanError("cloud.hosts: the hosts target needs at least one machine")
    groups = _replica_machines(manifest)
    taken = {name for names in groups.values() for name in names}
    free = [m.name for m in machines if m.name not in taken] or [m.name for m in machines]
    node_hosts = {node.name: groups[node.name][0] if node.name in groups else node.host or free[i % len(free)]
                  for i, node in enumerate(manifest.nodes)}
    carried = {name: [n.name for n in manifest.nodes if name in groups.get(n.name, ()) or
                      (n.name not in groups and node_hosts[n.name] == name)] for name in (m.name for m in machines)}
    for group, names in groups.items():
        for name in names:
            if carried[name] != [group]:
                others = ", ".join(n for n in carried[name] if n != group)
                raise PlanError(f"nodes.{group}: host {name!r} carries one of its replicas and {others} too; a "
                                "replica needs a host of its own (replica_hosts, or another host for the others)")
    master_port, relay_port = stack_ports(stack)
    hosts = []
    for machine in machines:
        placed = [n for n in manifest.nodes if n.name in carried[machine.name]]
        if not placed:
            continue
        for node in placed:
            if node.gpu and machine.gpus == 0:
                raise PlanError(f"nodes.{node.name}: needs a GPU but host {machine.name!r} has gpus: 0")
        hosts.append(HostSpec(
            name=machine.name, machine="lab", vcpus=0, gpus=machine.gpus, memory_gib=0.0, usd_per_hour=0.0,
            spot=False, disk_gb=0, nodes=tuple(n.name for n in placed), steps=steps_for(placed),
            tags=tags + (("fogiac:node", ",".join(n.name for n in placed)),),
            address=machine.address, user=machine.user, port=machine.port, key=str(machine.key),
            runtime=manifest.cloud.runtime, master_port=master_port, relay_port=relay_port,
        ))
    return Placement(hosts=tuple(hosts), node_hosts=node_hosts, mode="relay", connect_via="address",
                     autostop=autostop_for(manifest, power="services", default_minutes=None), replica_hosts=groups)


def _replica_machines(manifest: Manifest) -> dict[str, tuple[str, ...]]:
    """node -> the cloud.hosts entries carrying its replicas: its ``replica_hosts``, else the first
    machines no other node names (a replica shares its machine with nothing: the edge merges per host)."""
    machines = [m.name for m in manifest.cloud.hosts]
    named = {n.host for n in manifest.nodes if n.host} | {h for n in manifest.nodes for h in n.replica_hosts}
    groups: dict[str, tuple[str, ...]] = {}
    for node in manifest.nodes:
        if node.replicas == 1:
            continue
        if node.replica_hosts:
            groups[node.name] = node.replica_hosts
            continue
        used = {h for names in groups.values() for h in names}
        spare = [m for m in machines if m not in named and m not in used]
        if len(spare) < node.replicas:
            raise PlanError(f"nodes.{node.name}: replicas: {node.replicas} needs {node.replicas} hosts of its own, "
                            f"cloud.hosts has {len(spare)} spare; list them in replica_hosts")
        groups[node.name] = tuple(spare[:node.replicas])
    return groups
