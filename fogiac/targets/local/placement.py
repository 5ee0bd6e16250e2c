"""Where the ``local`` target puts a manifest's nodes: one sandbox per node (per replica of a
replicated node), on loopback."""

from __future__ import annotations

from fogiac.manifest.schema import Manifest
from fogiac.plan.placement import Placement, Tags, autostop_for, host_per_node, replica_groups


def place(manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
    hosts, node_hosts = host_per_node(manifest, stack=stack, tags=tags, address="127.0.0.1",
                                      runtime=manifest.cloud.runtime)
    return Placement(hosts=hosts, node_hosts=node_hosts, mode="relay", connect_via="loopback",
                     autostop=autostop_for(manifest, power="services", default_minutes=None),
                     replica_hosts=replica_groups(manifest))
