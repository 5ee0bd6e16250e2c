"""Nimbus's part of compile: one machine per node, at its catalogue price, reached on loopback."""

from __future__ import annotations

from fogiac.manifest.schema import Manifest
from fogiac.plan.model import CostLine
from fogiac.plan.placement import Placement, Tags, host_per_node
from tests.plugins.nimbus.catalogue import SHAPES


def place(manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
    hosts, node_hosts = host_per_node(manifest, stack=stack, tags=tags, address="127.0.0.1",
                                      usd_per_hour=lambda spec: SHAPES[spec.name].usd_per_hour,
                                      runtime=manifest.cloud.runtime)
    cost = tuple(CostLine(item=f"nimbus machine {h.name} ({h.machine})", quantity=1, usd_per_hour=h.usd_per_hour)
                 for h in hosts)
    return Placement(hosts=hosts, node_hosts=node_hosts, mode="relay", connect_via="loopback", cost=cost)
