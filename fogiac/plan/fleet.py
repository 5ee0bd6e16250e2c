"""What a fleet plan says about its robots and whom each node serves, as plain rows for tables and JSON.

Pure, like :mod:`fogiac.plan.cost`: everything comes from the compiled Plan. A robot is what adding or
removing it changes, and nothing else: its certificate, its access rules (its namespace ``/<robot>/...``
and the topics of the nodes that serve it) and its edge links, one to each host; no host is part of it,
so a reviewer sees that a robot comes and goes without a machine touched.

A node's hourly cost is its host's, split evenly between the nodes on the host; each robot it serves
bears an equal share of it (a per-robot node's instances share its host the same way). A robot's cost is
the sum of its shares: the robots' costs add up to the hosts'. An unknown price makes every share it
enters unknown (None), never $0.
"""

from __future__ import annotations

from typing import Any

from fogiac.certs import edge_identity
from fogiac.net import middleware
from fogiac.plan.model import NodeSpec, Plan


def instances(plan: Plan, node: NodeSpec) -> int:
    """How many copies of ``node`` run: one per robot for ``serve: per_robot``, else one every robot shares."""
    return len(plan.robots_of(node)) if node.per_robot else 1


def node_usd_per_hour(plan: Plan, node: NodeSpec) -> float | None:
    """The node's part of its host's hour (None: the host's price is unknown)."""
    host = plan.host(node.host)
    if host.usd_per_hour is None:
        return None
    return host.usd_per_hour / max(1, len(host.nodes))


def share(plan: Plan, node: NodeSpec) -> float | None:
    """What each robot ``node`` serves bears of its hour."""
    hourly = node_usd_per_hour(plan, node)
    return None if hourly is None else round(hourly / len(plan.robots_of(node)), 6)


def node_row(plan: Plan, node: NodeSpec) -> dict[str, Any]:
    """A fleet node's row additions: whom it serves, its instances and each robot's share of its hour."""
    return {"serves": list(plan.robots_of(node)), "serve": "per_robot" if node.per_robot else
            "all" if not node.serves else "list", "instances": instances(plan, node),
            "usd_per_hour_per_robot": share(plan, node)}


def access(plan: Plan, robot: str) -> list[str]:
    """The topics a robot may cross: its namespace, and the topics of the shared nodes that serve it."""
    shared = {topic for node in plan.nodes if robot in plan.robots_of(node) and not node.per_robot
              for topic in (*node.topics_in, *node.topics_out)}
    return [f"/{robot}/..."] + sorted(shared)


def robot_cost(plan: Plan, robot: str) -> float | None:
    """The robot's share of the hosts' hour: the sum of its nodes' shares (None when one is unknown)."""
    shares = [share(plan, node) for node in plan.nodes if robot in plan.robots_of(node)]
    if any(each is None for each in shares):
        return None
    return round(sum(each for each in shares if each is not None), 6)


def robots(plan: Plan) -> list[dict[str, Any]] | None:
    """Each robot of a fleet with what it brings: its certificate, access rules, edge links and cost share;
    None for a plan of one robot (``edge:``), whose document stays as it was."""
    if not plan.fleet:
        return None
    # the middleware names its robots' certificates where it has its own (Zenoh's edge routers'), else the relay's
    named = getattr(middleware.get(plan.middleware), "robot_certificate", None)
    return [{"name": edge.name, "entry": edge.entry,
             "certificate": named(plan.stack, edge.name) if named is not None and edge.named is not None
             else edge_identity(plan.stack, edge.named),
             "access": access(plan, edge.name), "edge_links": [route.host for route in plan.routes],
             "nodes": [node.name for node in plan.nodes if edge.name in plan.robots_of(node)],
             "usd_per_hour": robot_cost(plan, edge.name)}
            for edge in plan.edges]
